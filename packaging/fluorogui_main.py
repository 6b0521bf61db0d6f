"""Entry script of the standalone build (PyInstaller): the same dispatch as the installed
``fluorogui`` command: the desktop app, or a headless sub-command."""
import multiprocessing
import sys

from fluorogui.__main__ import main

if __name__ == "__main__":
    multiprocessing.freeze_support()  # batch's Dask workers re-run this executable
    sys.exit(main())

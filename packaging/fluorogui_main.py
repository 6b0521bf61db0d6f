"""Entry script of the standalone build (PyInstaller): the same dispatch as the installed
``fluorogui`` command: the desktop app, or a headless sub-command. With
``FLUOROGUI_BUILD_CHECK`` set it runs ``build.py --check``'s in-app checks instead
(``frozen_check``)."""
import multiprocessing
import os
import sys

from fluorogui.__main__ import main

if __name__ == "__main__":
    multiprocessing.freeze_support()  # batch's Dask workers re-run this executable
    if os.environ.get("FLUOROGUI_BUILD_CHECK"):
        import frozen_check

        sys.exit(frozen_check.main(os.environ["FLUOROGUI_BUILD_CHECK"]))
    sys.exit(main())

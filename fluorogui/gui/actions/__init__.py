"""The menu and action groups of the main window, each an object the window owns: files, editing, view, model,
matching, review, knee and help."""

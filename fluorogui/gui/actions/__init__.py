"""The main window's menu and action groups, each an object the window owns (files, edit, view, model, tasks...)."""

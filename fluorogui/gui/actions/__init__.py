"""The main window's presenters: each keeps a part of the window in step with the session and
turns what the user does there into workflow calls (files, edit, view, model, tasks, review,
help, and the Kinematics, Session, Frames and Pose panels'). Each is given what it needs;
the actions that call them are declared in ``gui.layout.actions``."""

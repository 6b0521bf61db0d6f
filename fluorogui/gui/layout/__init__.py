"""The main window declared as data: its panels (docks), presenters, actions, menus and
toolbar are specs (``specs``) listed in ``panels`` and ``actions``, from which ``build``
makes the Qt objects. Adding a panel or an action is adding a spec (see the developer
page *Adding a panel*)."""

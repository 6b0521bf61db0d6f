"""Old path of ``fluorogui.workflow.session.history``, kept only for ``workflow/exports.py``
until the export registry (issue 45, being rewritten elsewhere) imports the new one; then
delete this module."""
from fluorogui.workflow.session.history import Command, CommandStack

__all__ = ["Command", "CommandStack"]

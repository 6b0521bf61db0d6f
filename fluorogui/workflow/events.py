"""Old path of ``fluorogui.workflow.session.events``, kept only for ``workflow/exports.py``
until the export registry (issue 45, being rewritten elsewhere) imports the new one; then
delete this module."""
from fluorogui.workflow.session.events import HistoryEvent, SessionEvent

__all__ = ["HistoryEvent", "SessionEvent"]

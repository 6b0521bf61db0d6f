"""Old path of ``fluorogui.workflow.session.knee``, kept only for ``workflow/exports.py``
until the export registry (issue 45, being rewritten elsewhere) imports the new one; then
delete this module."""
from fluorogui.workflow.session.knee import KNEE_COMPONENTS, KNEE_KEY, KneeRow, record_sd

__all__ = ["KNEE_COMPONENTS", "KNEE_KEY", "KneeRow", "record_sd"]

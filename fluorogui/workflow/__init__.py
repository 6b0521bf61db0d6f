"""The Qt-free workflow the app, the CLI and scripts share: sessions, matching, tracking, calibration, exports."""
from fluorogui.core.search.find import Placement
from fluorogui.core.status import Status
from fluorogui.workflow.results import FrameResult
from fluorogui.workflow.session import FrameState, Session
from fluorogui.workflow.settings import TrackingSettings, WorkflowSettings

__all__ = ["FrameResult", "FrameState", "Placement", "Session", "Status", "TrackingSettings", "WorkflowSettings"]

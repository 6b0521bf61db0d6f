"""The Qt-free workflow: sessions, the matching loop with quality checks, find implants,
tracking and batch runs. The desktop app, the command line and scripts all call it."""
from fluorogui.workflow.results import FAILED, MATCHED, NEEDS_REVIEW, PLACED, FrameResult, Placement
from fluorogui.workflow.session import FrameState, Session
from fluorogui.workflow.settings import TrackingSettings, WorkflowSettings

__all__ = ["FAILED", "MATCHED", "NEEDS_REVIEW", "PLACED", "FrameResult", "FrameState", "Placement", "Session",
           "TrackingSettings", "WorkflowSettings"]

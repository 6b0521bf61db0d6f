"""The session and its parts: one open project, its undo history, its events, the edits, the
work (match, find, track), the knee and crash recovery (see ``session.py`` for how the parts
compose). ``from fluorogui.workflow.session import Session`` is the public way in."""
from fluorogui.workflow.session.cache import IMAGE_CACHE_FRAMES
from fluorogui.workflow.session.edits import ORIENTATION_PRESETS, fitted_outline
from fluorogui.workflow.session.reader import COMPONENT_ORDER, SINGLE_PLANE_DEPTH, FrameState
from fluorogui.workflow.session.session import Session

__all__ = ["COMPONENT_ORDER", "IMAGE_CACHE_FRAMES", "ORIENTATION_PRESETS", "SINGLE_PLANE_DEPTH", "FrameState",
           "Session", "fitted_outline"]

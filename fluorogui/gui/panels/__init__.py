"""The widgets inside the main window: the image panels with their items and editing tools, the matcher, pose,
kinematics, timeline and pixel-value panels."""

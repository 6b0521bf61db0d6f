"""The widgets inside the main window: image panels (items, editing tools), matcher, pose, kinematics, timeline."""

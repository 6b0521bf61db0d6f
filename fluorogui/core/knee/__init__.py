"""The knee: anatomical frames of the components and Grood-Suntay joint kinematics."""

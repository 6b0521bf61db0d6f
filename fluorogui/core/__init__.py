"""Pure computation (numpy, scipy, OpenCV). Never imports Qt, VTK rendering or file formats."""

"""Implant surface models in: STL, PLY, OBJ, VTK and VTP files, their headers checked before anything is allocated."""

"""Scripted motion on the host (NumPy, SciPy): paths, vehicle poses and rear-tire kinematics. Never imports
Taichi."""

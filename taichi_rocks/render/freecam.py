"""The view's free camera: GGUI's ``Camera.track_user_inputs`` (W/A/S/D forward, left, back, right, E/Q up and
down, the mouse with the right button held to look round) in the simulation's Z-up local frame.

``track_user_inputs`` assumes a Y-up world (its yaw and pitch are about GGUI's Y axis), so the GGUI camera it
moves lives in a helper frame, Y up: p_helper = M p_local with M the rotation taking +Z to +Y,
(x, y, z) -> (x, z, -y); the eye and the aim point come back through M^T. The local frame moves with the
floating origin: when the origin jumps the camera is moved by the opposite amount, so it stays put in the world.
"""

import numpy as np
import taichi as ti

from .camera import View, frame_of

__all__ = ["FreeCamera", "TO_HELPER"]

TO_HELPER = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # local Z-up -> GGUI's Y-up
SPEED = 0.12  # m per 1/60 s (~7 m/s)


class FreeCamera:
    """A camera the user moves. :meth:`start` puts it where a view is; :meth:`update` moves it by this frame's
    input and returns its view (local f32, the camera's basis)."""

    def __init__(self, speed: float = SPEED):
        self.speed = float(speed)
        self.ggui = ti.ui.Camera()  # the GGUI camera track_user_inputs moves (in the helper frame)
        self.origin = None

    def start(self, view: View, origin) -> None:
        self.origin = np.asarray(origin, np.float64).copy()
        self.ggui.position(*(TO_HELPER @ np.asarray(view.eye, np.float64)))
        self.ggui.lookat(*(TO_HELPER @ np.asarray(view.target, np.float64)))
        self.ggui.up(0.0, 1.0, 0.0)
        self.ggui.last_time = None
        self.ggui.last_mouse_x = self.ggui.last_mouse_y = None

    def forget_mouse(self) -> None:
        """The next drag starts afresh (the mouse state belonged to a window that is gone)."""
        self.ggui.last_mouse_x = self.ggui.last_mouse_y = None

    def _helper(self, which) -> np.ndarray:
        return np.array([float(which[k]) for k in range(3)])

    def update(self, window, origin, heading: float, move: bool = True) -> View:
        """Follow the floating origin, apply this frame's keys and mouse, return the view; ``move`` False: the
        mouse only (the keys drive a vehicle: app/driving.py)."""
        origin = np.asarray(origin, np.float64)
        if self.origin is not None and np.any(origin != self.origin):
            move = TO_HELPER @ (self.origin - origin)  # the same world point in the new local frame
            self.ggui.position(*(self._helper(self.ggui.curr_position) + move))
            self.ggui.lookat(*(self._helper(self.ggui.curr_lookat) + move))
        self.origin = origin.copy()
        self.ggui.track_user_inputs(window, movement_speed=self.speed if move else 0.0, hold_key=ti.ui.RMB)
        return self.view(heading)

    def view(self, heading: float) -> View:
        eye = (TO_HELPER.T @ self._helper(self.ggui.curr_position)).astype(np.float32)
        target = (TO_HELPER.T @ self._helper(self.ggui.curr_lookat)).astype(np.float32)
        return frame_of(eye, target, heading)

"""The reference planner from Python: plan on camera frames.

    >>> import fogline.world, fogline.planner
    >>> clip = fogline.world.clip(5, clips=8)                            # doctest: +SKIP
    >>> out = fogline.planner.plan(clip)                                 # doctest: +SKIP
    >>> out.decision, out.trajectory.shape                               # doctest: +SKIP
    ('follow', (64, 2))

The planner is camera-only: it sees the frames of its cameras (``front_wide`` needed,
``front_tele`` extends its range) and the ego history, nothing else (``docs/world.md``).
"""

import json

import numpy as np

from ._fogline import planner_plan as _plan

__all__ = ["plan", "Plan"]


class Plan:
    """The planner's answer.

    Attributes:
        trajectory: float64 array ``(64, 2)``: waypoints (x forward, y left) in metres at
            0.1 s steps.
        explanation: one sentence, worded from what was perceived.
        decision: ``keep_lane``, ``follow``, ``stop``, ... (or ``None``).
    """

    def __init__(self, d):
        self.trajectory = np.asarray(d["trajectory"]["xy"], dtype=np.float64).reshape(-1, 2)
        self.explanation = d["explanation"]
        self.decision = d.get("decision")

    def ade(self, ground_truth):
        """Average displacement error against a ``(64, 2)`` ground truth, m."""
        gt = np.asarray(ground_truth, dtype=np.float64)
        return float(np.linalg.norm(self.trajectory - gt, axis=1).mean())

    def __repr__(self):
        return f"Plan(decision={self.decision!r}, explanation={self.explanation!r})"


def plan(frames, ego_history=None, calibs=None):
    """Run the reference planner.

    Args:
        frames: a :class:`fogline.world.Clip`, or ``{camera: uint8 array (T, H, W, 3)}``
            (frames oldest first, or one ``(H, W, 3)`` frame) — for instance perturbed with
            :func:`fogline.perturb`.
        ego_history: float64 ``(N, 5)``: t, x, y, yaw, speed per row, oldest first ending at
            t = 0 (taken from the clip when ``frames`` is one).
        calibs: ``{camera: calibration dict}``; default: the standard rig at the frames' size
            (the clip's own when ``frames`` is one).

    Returns:
        A :class:`Plan`.
    """
    if hasattr(frames, "frames") and hasattr(frames, "ego_history"):
        clip = frames
        frames = clip.frames
        if ego_history is None:
            ego_history = clip.ego_history
        if calibs is None:
            calibs = clip.calibs
    if ego_history is None:
        raise ValueError("ego_history: needed (N x 5: t, x, y, yaw, speed per row)")
    if not isinstance(frames, dict):
        raise TypeError(f"frames: expected a Clip or a dict camera -> array, got {type(frames).__name__}")
    calib_json = None
    if calibs is not None:
        calib_json = {k: json.dumps(v) for k, v in calibs.items() if k in frames}
    hist = np.ascontiguousarray(ego_history, dtype=np.float64)
    frames = {k: np.ascontiguousarray(v) if isinstance(v, np.ndarray) else v for k, v in frames.items()}
    return Plan(json.loads(_plan(frames, hist, calib_json)))

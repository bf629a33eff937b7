"""fogline's synthetic driving world from Python: render a clip to numpy arrays.

    >>> import fogline.world
    >>> clip = fogline.world.clip(0, clips=8, seed=3)                   # doctest: +SKIP
    >>> clip.frames["front_wide"].shape                                  # doctest: +SKIP
    (4, 320, 576, 3)

Clip ``index`` of a corpus of ``clips`` clips is the clip ``fogline world generate --clips
CLIPS --seed SEED`` writes as its ``index``-th directory: the same scene, the same pixels.
"""

import json

from ._fogline import world_clip as _world_clip
from ._fogline import world_scenarios as _world_scenarios

__all__ = ["clip", "Clip", "SCENARIOS"]

SCENARIOS = tuple(_world_scenarios())
"""The scenario labels of the world (the envelope paper's seven classes and OTHER)."""


class Clip:
    """One generated clip.

    Attributes:
        id, scenario: the clip's id (its directory name) and scenario label.
        frames: ``{camera: uint8 array (T, H, W, 3)}``, oldest frame first (T = 4, 0.1 s apart).
        depth: ``{camera: float32 array (T, H, W)}`` in metres (``inf`` for sky), or ``{}``.
        boxes: ``{camera: [per frame: list of dicts with class, track_id, x, y, width, height]}``.
        calibs: ``{camera: calibration dict}`` (``fx``, ``fy``, ``cx``, ``cy``, pose in the rig).
        ego_history: float64 array ``(16, 5)``: t, x, y, yaw, speed per row, oldest first.
        ground_truth: float64 array ``(64, 2)``: the expert's future waypoints (x, y), m.
        scene: what the world knows beyond the pixels (the expert's decision, facts); never
            for a planner's eyes.
    """

    def __init__(self, d):
        self.id = d["id"]
        self.scenario = d["scenario"]
        self.scene = json.loads(d["scene"])
        self.ego_history = d["ego_history"]
        self.ground_truth = d["ground_truth"]
        cams = d["cameras"]
        self.frames = {k: v["frames"] for k, v in cams.items()}
        self.depth = {k: v["depth"] for k, v in cams.items() if v["depth"] is not None}
        self.boxes = {k: v["boxes"] for k, v in cams.items()}
        self._calib_json = {k: v["calib"] for k, v in cams.items()}
        self.calibs = {k: json.loads(v) for k, v in self._calib_json.items()}

    @property
    def decision(self):
        """The expert's decision (``stop``, ``follow``, ...), the planner's target."""
        return self.scene.get("decision")

    def __repr__(self):
        shapes = ", ".join(f"{k} {tuple(v.shape)}" for k, v in self.frames.items())
        return f"Clip({self.id!r}, {self.scenario}, {shapes})"


def clip(index, *, clips=1996, seed=0, mix="paper", scenario=None, width=576, height=320,
         depth=True, cameras=None):
    """Generate clip ``index`` of a corpus of ``clips`` clips.

    Args:
        index: which clip (``0 <= index < clips``).
        clips, seed, mix, scenario: the corpus, as ``fogline world generate`` takes it
            (``mix="paper"`` scales the paper's scenario mix to ``clips``, ``"uniform"``
            spreads them evenly, ``scenario=`` makes every clip that scenario).
        width, height: the image size of every camera (16 x 16 up to 1920 x 1080).
        depth: render depth maps too.
        cameras: the cameras to render (default all four: ``cross_left``, ``front_wide``,
            ``cross_right``, ``front_tele``); the others are not rendered.

    Returns:
        A :class:`Clip`. The GIL is released while it renders.
    """
    return Clip(_world_clip(
        int(index), clips=int(clips), seed=int(seed), mix=mix, scenario=scenario,
        width=int(width), height=int(height), depth=bool(depth),
        cameras=None if cameras is None else list(cameras),
    ))

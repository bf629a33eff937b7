"""The LLM-RCO controller from Python: what a CARLA agent's ``run_step`` needs.

    >>> import numpy as np, fogline.rco
    >>> ctl = fogline.rco.Controller()                                   # offline rules backend
    >>> frame = np.zeros((320, 576, 3), np.uint8)
    >>> d = ctl.step({"front_wide": frame}, {"front_wide": [(200, 150, 40, 60)]}, speed=6.0)
    >>> 0.0 <= d.throttle <= 1.0 and 0.0 <= d.brake <= 1.0 and -1.0 <= d.steer <= 1.0
    True

Each call of :meth:`Controller.step` is one control tick (0.1 s by default): the camera
frames with the regions perception lost (boxes or a boolean mask per camera), the ego's
speed and the route, and the controller answers throttle, brake and steer (CARLA's
conventions: steer positive right) with everything behind them (:class:`Decision`). The
controller is the library's ``fogline_rco::Rco`` (``docs/rco.md``): hazard inference,
short-term motion planner, action condition verifier and safety constraint generator, asking
the offline ``rules`` backend or any OpenAI-compatible server (``backend="openai"``).
"""

import json

import numpy as np

from ._fogline import RcoController as _Controller
from ._fogline import mask_boxes as _mask_boxes

__all__ = ["Controller", "Decision", "CAMERAS", "mask_boxes"]

CAMERAS = ("cross_left", "front_wide", "cross_right", "front_tele")
_MODULES = {"hi": "hazard_inference", "st": "motion_planner", "av": "verifier", "sc": "safety_constraints"}


def mask_boxes(mask):
    """The boxes ``(x, y, width, height)`` of the connected regions of a 2-D deficit mask."""
    return _mask_boxes(np.ascontiguousarray(mask))


class Decision:
    """One tick's answer.

    Attributes:
        throttle, brake, steer: the control after the safety constraints (``[0, 1]``,
            ``[0, 1]``, ``[-1, 1]`` positive right).
        action: ``"behavior/speed"``, e.g. ``"stop/deceleration_to_zero"``.
        source: ``plan``, ``wait``, ``hold`` or ``fallback``.
        strategy: ``move``, ``stop-observe-move`` or ``None``.
        fallback: ``None``, or why the safe fallback ran.
        summary: one line for logs.
        data: the whole ``Decision`` (hazards, constraints, verifier states, counters, ...).
    """

    def __init__(self, data, summary):
        self.data = data
        self.summary = summary
        c = data["control"]
        self.throttle = float(c["throttle"])
        self.brake = float(c["brake"])
        self.steer = float(c["steer"])
        a = data["action"]
        self.action = f"{a['behavior']}/{a['speed']}"
        self.source = data["source"]
        self.strategy = data.get("strategy")
        self.fallback = data.get("fallback")

    def carla_control(self):
        """``carla.VehicleControl(throttle, steer, brake)`` when the carla package is present,
        else a dict with those keys."""
        try:
            import carla  # noqa: F401  (only inside a CARLA client)

            return carla.VehicleControl(throttle=self.throttle, steer=self.steer, brake=self.brake)
        except ImportError:
            return {"throttle": self.throttle, "steer": self.steer, "brake": self.brake}

    def __repr__(self):
        return (f"Decision(throttle={self.throttle:.2f}, brake={self.brake:.2f}, "
                f"steer={self.steer:+.2f}, action={self.action!r}, source={self.source!r})")


def _box(b, what):
    if isinstance(b, dict):
        try:
            return {"x_px": float(b["x"]), "y_px": float(b["y"]),
                    "width_px": float(b["width"]), "height_px": float(b["height"])}
        except KeyError as e:
            raise ValueError(f"{what}: missing field {e.args[0]!r} (x, y, width, height)") from None
    try:
        x, y, w, h = b
    except (TypeError, ValueError):
        raise TypeError(f"{what}: expected (x, y, width, height) or a dict, got {b!r}") from None
    return {"x_px": float(x), "y_px": float(y), "width_px": float(w), "height_px": float(h)}


def _regions(value, what):
    """Boxes from a list of boxes or a 2-D mask array."""
    if value is None:
        return []
    if isinstance(value, np.ndarray):
        if value.ndim != 2:
            raise ValueError(f"{what}: a mask must be 2-D (H, W), got shape {value.shape}")
        return [_box(b, what) for b in mask_boxes(value)]
    return [_box(b, f"{what}[{i}]") for i, b in enumerate(value)]


def _objects(value, what):
    out = []
    for i, o in enumerate(value or []):
        if not isinstance(o, dict) or "class" not in o:
            raise TypeError(f"{what}[{i}]: expected a dict with class, x, y, width, height")
        obj = {"class": str(o["class"]), "rect": _box(o, f"{what}[{i}]")}
        if o.get("track_id") is not None:
            obj["track_id"] = int(o["track_id"])
        out.append(obj)
    return out


class Controller:
    """The LLM-RCO controller, stepped once per control tick.

    Args:
        backend: ``"rules"`` (offline, deterministic) or ``"openai"`` (any OpenAI-compatible
            chat-completions server).
        modules: the modules that are on: ``"hi,st,av,sc"`` (all), ``"none"`` or a subset
            (the paper's ablation).
        views: the cameras the controller reasons over.
        url, model, api_key_env, timeout_ms, send_images: the ``openai`` backend's settings
            (the key is read from the environment variable, never passed).
        **params: further ``RcoParams`` fields by name (``plan_limit``, ``dt_s``, ...).
    """

    def __init__(self, backend="rules", *, modules="hi,st,av,sc",
                 views=("cross_left", "front_wide", "cross_right"), url=None, model=None,
                 api_key_env=None, timeout_ms=None, send_images=None, **params):
        flags = {v: False for v in _MODULES.values()}
        for part in [p.strip().lower() for p in str(modules).split(",") if p.strip()]:
            if part == "none":
                continue
            if part not in _MODULES:
                raise ValueError(f"modules: unknown module {part!r} (hi, st, av, sc or none)")
            flags[_MODULES[part]] = True
        for v in views:
            if v not in CAMERAS:
                raise ValueError(f"views: unknown camera {v!r}; expected some of {', '.join(CAMERAS)}")
        params = dict(params, modules=flags, views=list(views))
        openai = {k: v for k, v in {"base_url": url, "model": model, "api_key_env": api_key_env,
                                    "timeout_ms": timeout_ms, "send_images": send_images}.items()
                  if v is not None}
        if backend != "openai" and openai:
            raise ValueError(f"{', '.join(openai)}: settings of the openai backend, not of {backend!r}")
        self._ctl = _Controller(json.dumps(params), backend, json.dumps(openai))
        self._tick = 0

    @property
    def backend(self):
        """The backend's description."""
        return self._ctl.backend()

    def reset(self):
        """Forget the plan, hazards and history (a new route); ticks restart at 0."""
        self._ctl.reset()
        self._tick = 0

    def step(self, frames=None, deficits=None, speed=0.0, *, accel=0.0, yaw_rate=0.0,
             follow_distance=None, direction="follow_lane", target=(10.0, 0.0),
             road="straight", two_way=True, lanes=2, objects=None, weather="clear",
             daylight="day", traffic_env="urban", traffic_density=0, image_size=None):
        """One control tick.

        Args:
            frames: ``{camera: uint8 H x W x 3 array}`` (cameras of :data:`CAMERAS`), or one
                array for ``front_wide``. Optional: without pixels the verifier works on the
                boxes alone and the ``openai`` backend sends text only.
            deficits: ``{camera: regions}``: the pixels perception lost, as a list of boxes
                ``(x, y, width, height)`` (or dicts with those keys) or a 2-D mask (non-zero
                = lost). A configured camera missing from both ``frames`` and ``deficits``
                counts as one full-frame deficit.
            speed: ego speed, m/s. ``accel``: m/s^2; ``yaw_rate``: rad/s, left positive;
                ``follow_distance``: m to the vehicle ahead (``None``: nobody).
            direction: ``follow_lane``, ``straight``, ``left``, ``right``,
                ``change_lane_left``, ``change_lane_right``; ``target``: next route point
                ``(x forward, y left)`` in metres; ``road``: ``straight``, ``curve``,
                ``junction``, ``roundabout``.
            objects: ``{camera: [dicts with class, x, y, width, height, track_id]}``: the
                traffic objects perception still sees.
            weather, daylight, traffic_env, traffic_density: the surroundings (CARLA's
                weather presets in snake case, ``day``/``sunset``/``night``, ...).
            image_size: ``(width, height)`` of views given by ``deficits`` only.

        Returns:
            A :class:`Decision`.
        """
        if frames is None:
            frames = {}
        elif isinstance(frames, np.ndarray):
            frames = {"front_wide": frames}
        deficits = deficits or {}
        objects = objects or {}
        for what, d in (("frames", frames), ("deficits", deficits), ("objects", objects)):
            if not isinstance(d, dict):
                raise TypeError(f"{what}: expected a dict camera -> value, got {type(d).__name__}")
            for cam in d:
                if cam not in CAMERAS:
                    raise ValueError(f"{what}: unknown camera {cam!r}; expected one of {', '.join(CAMERAS)}")
        views = []
        arrays = {}
        for cam in CAMERAS:
            if cam not in frames and cam not in deficits and cam not in objects:
                continue
            if cam in frames:
                a = frames[cam]
                if not isinstance(a, np.ndarray) or a.ndim != 3 or a.shape[2] != 3:
                    raise ValueError(f"frames[{cam!r}]: expected an H x W x 3 uint8 array")
                height, width = a.shape[:2]
                arrays[cam] = a
            elif image_size is not None:
                width, height = image_size
            else:
                raise ValueError(f"{cam}: no frame to take its size from: pass its frame or image_size=(W, H)")
            views.append({
                "camera": cam, "width": int(width), "height": int(height),
                "deficits": _regions(deficits.get(cam), f"deficits[{cam!r}]"),
                "objects": _objects(objects.get(cam), f"objects[{cam!r}]"),
            })
        tx, ty = target
        obs = {
            "tick": self._tick,
            "views": views,
            "ego": {"speed_mps": float(speed), "accel_x_mps2": float(accel),
                    "yaw_rate_rps": float(yaw_rate)},
            "navigation": {"direction": direction, "target_x_m": float(tx), "target_y_m": float(ty),
                           "road": {"layout": road, "two_way": bool(two_way), "lanes": int(lanes)}},
            "surroundings": {"weather": weather, "daylight": daylight, "traffic_env": traffic_env,
                             "traffic_density": int(traffic_density)},
        }
        if follow_distance is not None:
            obs["ego"]["follow_distance_m"] = float(follow_distance)
        decision = self.step_observation(obs, arrays)
        return decision

    def step_observation(self, observation, frames=None):
        """One tick from a full observation dict (the replay format of ``docs/rco.md``,
        without ``rgb``) and ``{camera: array}`` frames; advances the tick counter past it."""
        text, summary = self._ctl.step(json.dumps(observation), dict(frames or {}))
        self._tick = int(observation.get("tick", self._tick)) + 1
        return Decision(json.loads(text), summary)

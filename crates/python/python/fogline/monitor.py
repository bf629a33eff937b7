"""The runtime ODD monitor from Python: blind condition estimates of numpy frames, and the
monitor that steps over them against an envelope's ``odd.json``.

    >>> import numpy as np, fogline.monitor
    >>> frame = np.full((48, 64, 3), 120, np.uint8)
    >>> e = fogline.monitor.estimate(frame)
    >>> e["noise_sigma"], e["noise_sigma_se"]
    (0.0, 0.0)

:func:`estimate` measures one ``uint8`` ``(H, W, 3)`` frame: Gaussian noise sigma (0-255
scale), photometric gain and fog opacity, each with its standard error (the library's
``fogline_monitor::estimate_frame``, as ``fogline monitor estimate`` prints them).
:class:`Monitor` is ``fogline_monitor::Monitor``: per-frame estimates smoothed over time,
compared conservatively with the scenario's thresholds in ``odd.json`` (noise, darken,
brighten, fog), with hysteresis and a minimum dwell; each :meth:`Monitor.step` returns the
record ``fogline monitor run`` prints as a JSON line, as a dict (``docs/monitor.md``).
"""

import json
import os

import numpy as np

from ._fogline import MonitorCore as _Core
from ._fogline import monitor_defaults as _defaults
from ._fogline import monitor_estimate as _estimate

__all__ = ["estimate", "Monitor", "defaults", "ESTIMATED_AXES"]

ESTIMATED_AXES = ("gaussian_noise", "darken", "brighten", "fog")


def defaults():
    """The monitor's default parameters (``MonitorParams``) as a dict."""
    return json.loads(_defaults())


def _frame(image, what):
    if not isinstance(image, np.ndarray):
        raise TypeError(f"{what}: expected a numpy uint8 array of shape (H, W, 3), got {type(image).__name__}")
    return np.ascontiguousarray(image)


def estimate(image, *, condition=None):
    """Blind estimates of one RGB frame.

    Args:
        image: a numpy ``uint8`` array of shape ``(H, W, 3)`` (at least 3x3).
        condition: optional ``ConditionParams`` dict (``reference``, ``spread``,
            ``airlight``): the clean reference profile gain and fog are read against.

    Returns:
        A dict: ``noise_sigma``, ``noise_sigma_se``, ``gain``, ``gain_se``, ``fog``,
        ``fog_se``, ``clipped_share`` (the keys of ``fogline monitor estimate --json``
        without ``path``, ``width``, ``height`` and ``ms``).

    Raises:
        TypeError: not a numpy ``uint8`` array.
        ValueError: a wrong shape, or invalid ``condition``.
    """
    e = json.loads(_estimate(_frame(image, "image"), json.dumps(condition or {})))
    n, c = e["noise"], e["condition"]
    return {
        "noise_sigma": n["sigma"],
        "noise_sigma_se": n["sigma_se"],
        "gain": c["gain"],
        "gain_se": c["gain_se"],
        "fog": c["fog"],
        "fog_se": c["fog_se"],
        "clipped_share": n["clipped_share"],
    }


_OBSERVATION = ("noise_sigma", "noise_sigma_se", "gain", "gain_se", "fog", "fog_se")


class Monitor:
    """The runtime ODD monitor of one camera stream.

    Args:
        odd: the envelope's ``odd.json``: a path, its text, or the parsed dict.
        scenario: the entry used (e.g. ``"LANE_KEEPING"``; change it with
            :meth:`set_scenario`, for instance from the planner's decision).
        **params: ``MonitorParams`` fields to override (``ewma_alpha``, ``z``,
            ``min_dwell_steps``, ``noise_margin``, ``gain_margin``, ``fog_margin``,
            ``axes``, ``faults_enabled``, ``condition``, ``temporal``; see :func:`defaults`).

    Raises:
        ValueError: an unreadable ``odd.json`` (the reason names the field), a scenario
            without an entry, an unknown or out-of-range parameter.

    Example::

        m = Monitor("fogline-demo/odd.json", "LANE_KEEPING", min_dwell_steps=5)
        for frame in frames:                    # numpy uint8 (H, W, 3)
            r = m.step(frame)
            if not r["in_envelope"]:
                hand_over(r["reason"], r["quadrant"])
    """

    def __init__(self, odd, scenario, **params):
        if isinstance(odd, dict):
            text = json.dumps(odd)
        elif isinstance(odd, (str, os.PathLike)) and not str(odd).lstrip().startswith("{"):
            with open(odd, encoding="utf-8") as f:
                text = f.read()
        elif isinstance(odd, str):
            text = odd
        else:
            raise TypeError(f"odd: expected a path, a JSON text or a dict, got {type(odd).__name__}")
        self._core = _Core(text, scenario, json.dumps(params))

    def step(self, frame):
        """One step: ``frame`` is a numpy ``uint8`` ``(H, W, 3)`` frame (measured here, with
        the temporal-fault detector), or a dict of estimates with the keys
        ``noise_sigma``, ``noise_sigma_se``, ``gain``, ``gain_se``, ``fog``, ``fog_se``
        (what :func:`estimate` returns). Returns the record as a dict: ``step``,
        ``in_envelope``, ``switched``, ``held``, ``reason``, ``quadrant``, ``fault``,
        ``axes`` (per watched axis: ``estimate``, ``smoothed``, ``bound``, ``limit``, ...)."""
        if isinstance(frame, dict):
            missing = [k for k in _OBSERVATION if k not in frame]
            if missing:
                raise ValueError(f"estimates: missing {', '.join(missing)}")
            obs = {k: float(frame[k]) for k in _OBSERVATION}
            return json.loads(self._core.step(json.dumps(obs)))
        return json.loads(self._core.step_frame(_frame(frame, "frame")))

    def set_scenario(self, scenario):
        """Use another scenario's entry from now on (the averages and the state are kept)."""
        self._core.set_scenario(scenario)

    def reset(self):
        """Forget the stream (a new clip or route)."""
        self._core.reset()

    @property
    def in_envelope(self):
        """The decision so far (``None`` before the first step)."""
        return self._core.in_envelope()

    @property
    def scenario(self):
        """The scenario whose entry is in use."""
        return self._core.scenario()

    @property
    def watched_axes(self):
        """The axes watched: those of ``axes`` the scenario's entry has a threshold for."""
        return list(self._core.watched_axes())

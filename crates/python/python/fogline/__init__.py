"""fogline: exact, seeded sensor corruptions for camera frames, from Python.

The same corruptions as the ``fogline`` command line (Gaussian noise, darkness, fog, the
robustness benchmarks' families, temporal faults and the LLM-RCO paper's deficit masks), on
numpy ``uint8`` arrays, with the same bytes for the same seed and stream key::

    >>> import numpy as np, fogline
    >>> frame = np.full((48, 64, 3), 128, dtype=np.uint8)
    >>> noisy = fogline.perturb(frame, "noise_30", seed=7, key="clip/0001.png")
    >>> noisy.shape, noisy.dtype
    ((48, 64, 3), dtype('uint8'))
    >>> bool((noisy == fogline.perturb(frame, "noise_30", seed=7, key="clip/0001.png")).all())
    True

The user guide is ``docs/python.md`` in the repository.
"""

from ._fogline import __version__, condition_name, stream_key
from ._fogline import perturb as _perturb
from . import dataset, envelope, monitor, planner, rco, world
from .transforms import AlbuPerturb, Perturb

__all__ = [
    "__version__",
    "perturb",
    "condition_name",
    "stream_key",
    "Perturb",
    "AlbuPerturb",
    "dataset",
    "envelope",
    "monitor",
    "rco",
    "world",
    "planner",
]


def perturb(
    image,
    condition,
    *,
    seed=0,
    key=None,
    out=None,
    boxes=None,
    depth=None,
    threads=1,
    return_regions=False,
):
    """Apply a condition to one RGB frame or a batch of them.

    Args:
        image: a C-contiguous numpy ``uint8`` array, ``(H, W, 3)`` for one frame or
            ``(N, H, W, 3)`` for a batch. Read in place (no copy).
        condition: a condition name in the CLI's grammar: ``"noise_30"``, ``"dark"``,
            ``"fog_07"``, ``"noise_30+fog_03"`` (steps applied left to right), ``"mask_all"``,
            ... (``fogline perturb --help`` lists every family).
        seed: the campaign seed; with the key it fixes every random draw.
        key: names each frame's random stream. A ``str`` is the frame's path relative to the
            CLI's input directory (``"clip/0001.png"``): the output is then byte-identical to
            ``fogline perturb --seed SEED`` on that file. An ``int`` is a frame number. For a
            batch, a list of one key per frame; by default frame ``i`` of a batch has key
            ``i`` and a single frame key ``0``.
        out: optional preallocated output, a writeable C-contiguous ``uint8`` array of the
            image's shape (not the image itself); by default one new array is allocated.
        boxes: objects to hide for deficit conditions (``mask_all``, ``mask_class_<c>``,
            ``mask_track_<id>``): a list of dicts with ``class``, ``x``, ``y``, ``width``,
            ``height`` (pixels, origin top-left) and optionally ``track_id``, or tuples
            ``(class, x, y, width, height)``; for a batch, one such list per frame.
        depth: metres per pixel, ``float32`` ``(H, W)`` (or ``(N, H, W)``), for
            Koschmieder fog (``visibility_<V>``; ``fog_<NN>`` uses it when given).
        threads: threads for a batch (``0``: all cores). The result does not depend on it.
        return_regions: also return the hidden regions (dicts with ``class``,
            ``track_id``, ``x``, ``y``, ``width``, ``height``), a list per frame.

    Returns:
        The perturbed array (``out`` when given), or ``(array, regions)`` with
        ``return_regions=True``.

    Raises:
        TypeError: ``image``, ``out`` or ``depth`` is not a numpy array of the right dtype,
            or an argument has the wrong type.
        ValueError: a wrong shape or layout (not C-contiguous), an unknown or invalid
            condition, a box outside the frame, a missing depth map or box list.

    Temporal conditions (``drop_<p>``, ``latency_<k>``, ``blackout_<f>``, ``freeze_<f>``)
    treat a batch as one clip in time order, as the CLI treats a directory. The GIL is
    released while pixels are computed.
    """
    return _perturb(
        image,
        condition,
        seed=seed,
        key=key,
        out=out,
        boxes=boxes,
        depth=depth,
        threads=threads,
        return_regions=return_regions,
    )

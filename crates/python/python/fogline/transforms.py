"""Transform classes over :func:`fogline.perturb` for data pipelines.

:class:`Perturb` fits ``torchvision.transforms.Compose`` (a callable on one image) and
:class:`AlbuPerturb` is called like an albumentations transform (``t(image=img)`` returns a
dict). Neither package is needed: images are numpy arrays, PIL images or torch tensors,
detected by duck typing.

Each call perturbs with the next frame number as the stream key, so successive calls draw
fresh noise, and a run is reproduced from ``seed`` alone. Data loaders that copy the
transform into worker processes should give each worker its own seed (``reseed``), or every
worker repeats the same draws.
"""

import numpy as np

from ._fogline import condition_name
from ._fogline import perturb as _perturb

__all__ = ["Perturb", "AlbuPerturb"]


def _to_hwc(img):
    """(array H x W x 3 uint8, a function that turns such an array back into img's type)."""
    if isinstance(img, np.ndarray):
        return img, lambda a: a
    if hasattr(img, "mode") and hasattr(img, "convert"):  # a PIL image
        from PIL import Image

        mode = img.mode
        arr = np.asarray(img.convert("RGB"))
        if mode == "RGB":
            return arr, Image.fromarray
        return arr, lambda a: Image.fromarray(a).convert(mode)
    if hasattr(img, "permute") and hasattr(img, "numpy"):  # a torch tensor, C x H x W
        import torch

        if img.dim() != 3 or img.shape[0] != 3:
            raise ValueError(f"image: expected a 3 x H x W tensor, got shape {tuple(img.shape)}")
        if img.dtype != torch.uint8:
            raise TypeError(f"image: expected a uint8 tensor, got {img.dtype}")
        device = img.device
        arr = np.ascontiguousarray(img.detach().cpu().permute(1, 2, 0).numpy())
        return arr, lambda a: torch.from_numpy(a).permute(2, 0, 1).to(device)
    raise TypeError(
        f"image: expected a numpy array, a PIL image or a torch tensor, got {type(img).__name__}"
    )


class Perturb:
    """A fogline condition as a ``torchvision``-style transform: ``Perturb("noise_30")(img)``.

    Args:
        condition: a condition name (``"noise_30"``, ``"fog_07"``, ``"noise_30+dark"``, ...).
        seed: fixes every draw; call ``k`` of this object uses stream key ``k``.
    """

    def __init__(self, condition, seed=0):
        self.condition = condition_name(condition)
        self.seed = int(seed)
        self._calls = 0

    def reseed(self, seed):
        """Restart the draws from ``seed`` (for instance one seed per data-loader worker)."""
        self.seed = int(seed)
        self._calls = 0

    def __call__(self, img):
        arr, back = _to_hwc(img)
        arr = np.ascontiguousarray(arr)
        key = self._calls
        self._calls += 1
        return back(_perturb(arr, self.condition, seed=self.seed, key=key))

    def __repr__(self):
        return f"Perturb(condition={self.condition!r}, seed={self.seed})"


class AlbuPerturb:
    """A fogline condition called like an albumentations transform: ``t(image=img)["image"]``.

    Args:
        condition: a condition name.
        seed: fixes every draw (the noise and whether the transform applies).
        p: probability of applying the condition to a call's image.

    Keys other than ``image`` (masks, boxes, keypoints) pass through unchanged: fogline's
    corruptions are photometric and move no pixel.
    """

    def __init__(self, condition, seed=0, p=1.0):
        if not 0.0 <= float(p) <= 1.0:
            raise ValueError(f"p: expected a probability in [0, 1], got {p}")
        self.condition = condition_name(condition)
        self.seed = int(seed)
        self.p = float(p)
        self._calls = 0
        self._rng = np.random.default_rng(self.seed)

    def __call__(self, *args, force_apply=False, **data):
        if args:
            raise TypeError("AlbuPerturb takes keyword arguments only: t(image=img)")
        if "image" not in data:
            raise TypeError("AlbuPerturb: missing the image= argument")
        key = self._calls
        self._calls += 1
        if force_apply or self._rng.random() < self.p:
            img = np.ascontiguousarray(data["image"])
            data = dict(data, image=_perturb(img, self.condition, seed=self.seed, key=key))
        return data

    def __repr__(self):
        return f"AlbuPerturb(condition={self.condition!r}, seed={self.seed}, p={self.p})"

from typing import Any, Literal, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

from ._fogline import Box, Key, __version__, condition_name, stream_key
from . import envelope as envelope
from . import planner as planner
from . import rco as rco
from . import world as world
from .transforms import AlbuPerturb, Perturb

@overload
def perturb(
    image: npt.NDArray[np.uint8],
    condition: str,
    *,
    seed: int = ...,
    key: Optional[Union[Key, Sequence[Key]]] = ...,
    out: Optional[npt.NDArray[np.uint8]] = ...,
    boxes: Optional[Union[Sequence[Box], Sequence[Sequence[Box]]]] = ...,
    depth: Optional[npt.NDArray[np.float32]] = ...,
    threads: int = ...,
    return_regions: Literal[False] = ...,
) -> npt.NDArray[np.uint8]: ...
@overload
def perturb(
    image: npt.NDArray[np.uint8],
    condition: str,
    *,
    seed: int = ...,
    key: Optional[Union[Key, Sequence[Key]]] = ...,
    out: Optional[npt.NDArray[np.uint8]] = ...,
    boxes: Optional[Union[Sequence[Box], Sequence[Sequence[Box]]]] = ...,
    depth: Optional[npt.NDArray[np.float32]] = ...,
    threads: int = ...,
    return_regions: Literal[True],
) -> Tuple[npt.NDArray[np.uint8], Any]: ...

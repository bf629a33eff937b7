"""Type stubs of fogline's compiled module."""

from typing import Any, Literal, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str

Key = Union[str, int]
Box = Union[dict, Tuple[str, float, float, float, float]]
Region = dict

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
def stream_key(rel: str) -> Tuple[int, int, int]: ...
def condition_name(condition: str) -> str: ...
def envelope_analyze(
    table: Any,
    params: str,
    *,
    taxonomy: str = ...,
    allow_incomplete: bool = ...,
    name: str = ...,
) -> Tuple[str, str]: ...
def envelope_defaults() -> str: ...
def envelope_synthetic_csv(path: str, clips: int, *, seed: int = ...) -> None: ...
def mask_boxes(mask: npt.NDArray[Any]) -> list[Tuple[float, float, float, float]]: ...

class RcoController:
    def __init__(self, params: str, backend: str = ..., openai: str = ...) -> None: ...
    def step(self, observation: str, frames: dict) -> Tuple[str, str]: ...
    def reset(self) -> None: ...
    def backend(self) -> str: ...

class MonitorCore:
    def __init__(self, odd: str, scenario: str, params: str = ...) -> None: ...
    def step_frame(self, image: npt.NDArray[np.uint8]) -> str: ...
    def step(self, observation: str) -> str: ...
    def set_scenario(self, scenario: str) -> None: ...
    def reset(self) -> None: ...
    def in_envelope(self) -> Optional[bool]: ...
    def scenario(self) -> str: ...
    def watched_axes(self) -> list[str]: ...

def monitor_estimate(image: npt.NDArray[np.uint8], condition: str = ...) -> str: ...
def monitor_defaults() -> str: ...
def dataset_deficit(out: str, params: str) -> Tuple[str, str]: ...
def dataset_import(logs: str, out: str, params: str) -> Tuple[str, str]: ...
def dataset_evaluate(
    data: str,
    *,
    split: str,
    limit: Optional[int],
    jobs: int,
    backend: str,
    openai: str,
    out: Optional[str],
    gallery: int,
) -> Tuple[str, str, list[str]]: ...

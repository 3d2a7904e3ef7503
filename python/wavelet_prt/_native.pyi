"""The native half of wavelet_prt: the engine's front door, as the package calls it. Use the
package's functions (``wavelet_prt.bake``, ``wavelet_prt.Transport``), which give these their
keyword names and defaults."""

from typing import Callable, List, Optional, Tuple

import numpy as np
import numpy.typing as npt

VERSION: str
DEFAULT_TERMS: int

def bake(
    scene: str,
    out: str,
    settings: str,
    camera: Optional[str] = None,
    width: Optional[int] = None,
    height: Optional[int] = None,
    read_outside_folder: bool = False,
    per_vertex: bool = False,
    edge_length: Optional[float] = None,
    visibility: Optional[bool] = None,
    progress: Optional[Callable[[int, int], object]] = None,
) -> str: ...
def default_settings() -> str: ...
def merge(shards: List[str], out: str) -> str: ...
def read_image(path: str) -> npt.NDArray[np.float32]: ...
def save_image(path: str, image: npt.NDArray[np.float32], exposure: Optional[float] = None) -> None: ...
def compare(
    image: npt.NDArray[np.float32],
    reference: npt.NDArray[np.float32],
    mask: Optional[npt.NDArray[np.float32]] = None,
) -> Tuple[float, float, float, float, float]: ...

class Environment:
    @staticmethod
    def from_spec(spec: str) -> "Environment": ...
    @staticmethod
    def from_array(pixels: npt.NDArray[np.float32]) -> "Environment": ...
    def pixels(self) -> npt.NDArray[np.float32]: ...
    @property
    def source(self) -> str: ...

class Transport:
    @staticmethod
    def open(path: str) -> "Transport": ...
    def meta_json(self) -> str: ...
    def relight(
        self,
        env: Optional[Environment],
        method: str,
        terms: int,
        weighting: str,
        sh_order: Optional[int],
        yaw: float,
        pitch: float,
        lights: List[str],
        background: str,
        eye: Optional[List[float]],
        target: Optional[List[float]],
        up: Optional[List[float]],
        width: Optional[int],
        height: Optional[int],
        samples: int,
    ) -> npt.NDArray[np.float32]: ...
    def time_relight(self, env: Environment, method: str, terms: int, repeats: int) -> List[float]: ...
    def coverage(self) -> npt.NDArray[np.float32]: ...
    def cube(self, env: Environment, yaw: float, pitch: float) -> npt.NDArray[np.float32]: ...
    def light(
        self, env: Environment, yaw: float, pitch: float
    ) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.float64]]: ...
    def kept_terms(
        self, env: Environment, terms: int, weighting: str, yaw: float, pitch: float
    ) -> Tuple[npt.NDArray[np.int64], npt.NDArray[np.float32]]: ...
    def row(self, pixel: int) -> npt.NDArray[np.float32]: ...
    def sh_row(self, pixel: int) -> npt.NDArray[np.float32]: ...
    def vertex_pixel(self, vertex: int) -> int: ...
    def prepared(self) -> int: ...

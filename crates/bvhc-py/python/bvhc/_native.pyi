"""Types of the native module ``bvhc._native`` (the package's public functions wrap it: see ``bvhc``)."""

from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np
import numpy.typing as npt

FORMAT_VERSION: str
RULE_COUNT: int

class Error(Exception): ...
class InvalidInputError(Error): ...
class InvalidFileError(Error): ...
class OptionsError(InvalidInputError): ...
class OutOfMemoryError(Error): ...
class IoError(Error): ...
class InternalError(Error): ...

def convert(
    src: str,
    dst: str,
    preset: str,
    options: Optional[Dict[str, Any]] = None,
    force: bool = False,
    threads: Optional[int] = None,
    progress: Optional[Callable[[str, Optional[int], Optional[float], Optional[float]], Any]] = None,
) -> str: ...
def resolve(preset: str, options: Optional[Dict[str, Any]] = None) -> str: ...
def options_table() -> str: ...
def run_job(job: str, force: bool = False, threads: Optional[int] = None) -> str: ...
def verify(path: str) -> str: ...

class Scene:
    def __init__(self, data: npt.NDArray[np.uint8], path: str, verify: bool = True) -> None: ...
    @property
    def path(self) -> str: ...
    @property
    def data(self) -> npt.NDArray[np.uint8]: ...
    @property
    def bounds(self) -> Optional[Tuple[Tuple[float, float, float], Tuple[float, float, float]]]: ...
    def info_json(self) -> str: ...
    def verify(self) -> None: ...
    @property
    def source_id_count(self) -> int: ...
    def refit(
        self,
        positions: Optional[npt.NDArray[np.float32]] = None,
        source_vertices: Optional[List[Optional[npt.NDArray[np.float32]]]] = None,
        threads: Optional[int] = None,
        max_cost_ratio: float = 1.2,
    ) -> Dict[str, Any]: ...
    def pose(
        self,
        asset: str,
        pose: Optional[str] = None,
        threads: Optional[int] = None,
        max_cost_ratio: float = 1.2,
    ) -> Dict[str, Any]: ...
    def move_instances(self, instances: List[int], transforms: npt.NDArray[np.float32]) -> None: ...
    def move_instances_in_frame(self, instances: List[int], transforms: npt.NDArray[np.float32]) -> None: ...
    def refit_mesh(self, mesh: int, positions: npt.NDArray[np.float32], threads: Optional[int] = None) -> None: ...
    def write(self, output: str) -> None: ...
    def closest_hits(
        self,
        origins: Any,
        directions: Any,
        t_min: Any,
        t_max: Any,
        threads: Optional[int] = None,
        cutout: Optional[npt.NDArray[np.bool_]] = None,
        cutout_primitives: Optional[Any] = None,
        filter: Optional[Callable[..., bool]] = None,
        filter_scope: str = "every",
        coherent: bool = False,
        lean: bool = False,
    ) -> Dict[str, npt.NDArray[Any]]: ...
    def any_hits(
        self,
        origins: Any,
        directions: Any,
        t_min: Any,
        t_max: Any,
        threads: Optional[int] = None,
        cutout: Optional[npt.NDArray[np.bool_]] = None,
        cutout_primitives: Optional[Any] = None,
        filter: Optional[Callable[..., bool]] = None,
        filter_scope: str = "every",
        coherent: bool = False,
    ) -> npt.NDArray[np.bool_]: ...
    def all_hits(
        self,
        origins: Any,
        directions: Any,
        t_min: Any,
        t_max: Any,
        max_hits: int = 64,
        threads: Optional[int] = None,
        cutout: Optional[npt.NDArray[np.bool_]] = None,
        cutout_primitives: Optional[Any] = None,
        filter: Optional[Callable[..., bool]] = None,
        filter_scope: str = "every",
    ) -> Dict[str, npt.NDArray[Any]]: ...
    def contains(self, points: Any, threads: Optional[int] = None) -> npt.NDArray[np.bool_]: ...
    def closest_points(
        self,
        points: Any,
        max_distance: Optional[float] = None,
        threads: Optional[int] = None,
        cutout: Optional[npt.NDArray[np.bool_]] = None,
        cutout_primitives: Optional[Any] = None,
    ) -> Dict[str, npt.NDArray[Any]]: ...
    def winding(self, points: Any, signed: bool, threads: Optional[int] = None) -> npt.NDArray[Any]: ...
    def spawn(
        self,
        t: npt.NDArray[np.float32],
        triangle: npt.NDArray[np.uint32],
        u: npt.NDArray[np.float32],
        v: npt.NDArray[np.float32],
        normal: Any,
        front_face: npt.NDArray[np.bool_],
        instance: npt.NDArray[np.uint32],
        source_id: npt.NDArray[np.uint32],
        directions: Any,
    ) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.float32], npt.NDArray[np.float32], npt.NDArray[np.float32]]: ...

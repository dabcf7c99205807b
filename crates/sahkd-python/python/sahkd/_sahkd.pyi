# Types of the compiled module (crates/sahkd-python/src). `stubtest` checks these against the
# built module in crates/sahkd-python/test.sh, and `mypy --strict` a typed example.

import os
from typing import Any, Literal, Optional, Union, final

import numpy as np
import numpy.typing as npt

from ._types import AllHits, Closest, Hits, SceneClosest, SceneHits

__all__ = ["KdTree", "Scene", "from_bytes", "load", "_read_mesh", "__version__"]

__version__: str

_Path = Union[str, "os.PathLike[str]"]
# A scalar for every ray, or one per ray.
_Bound = Union[float, npt.ArrayLike, None]
_Precision = Literal["f32", "f64"]
_Inside = Literal["parity", "winding"]
_Preset = Literal["fast", "balanced", "quality", "paper", "sweep"]
# Cost keywords: traversal, intersection, empty_bonus, max_duplication (floats), leaf_size,
# max_depth (ints).
_Cost = Union[float, int, None]

@final
class KdTree:
    """A kd-tree over a triangle mesh, for batched ray queries from numpy."""

    def __new__(
        cls,
        vertices: npt.ArrayLike,
        faces: npt.ArrayLike,
        preset: Optional[_Preset] = ...,
        algorithm: Optional[str] = ...,
        axes: Optional[str] = ...,
        counting: Optional[str] = ...,
        clip: Optional[bool] = ...,
        threads: Optional[int] = ...,
        bins: Optional[int] = ...,
        **cost: _Cost,
    ) -> KdTree: ...
    def __len__(self) -> int: ...
    @property
    def stats(self) -> dict[str, Any]: ...
    @property
    def bounds(self) -> npt.NDArray[np.float32]: ...
    @property
    def triangles(self) -> npt.NDArray[np.float32]: ...
    def _structure(self) -> tuple[npt.NDArray[np.uint32], npt.NDArray[np.uint32]]: ...
    def validate(self) -> None: ...
    def intersect(
        self,
        origins: npt.ArrayLike,
        directions: npt.ArrayLike,
        t_min: _Bound = ...,
        t_max: _Bound = ...,
        precision: _Precision = ...,
    ) -> Hits: ...
    def occluded(
        self,
        origins: npt.ArrayLike,
        directions: npt.ArrayLike,
        t_min: _Bound = ...,
        t_max: _Bound = ...,
        precision: _Precision = ...,
    ) -> npt.NDArray[np.bool_]: ...
    def count_hits(
        self,
        origins: npt.ArrayLike,
        directions: npt.ArrayLike,
        t_min: _Bound = ...,
        t_max: _Bound = ...,
    ) -> npt.NDArray[np.int64]: ...
    def intersect_all(
        self,
        origins: npt.ArrayLike,
        directions: npt.ArrayLike,
        t_min: _Bound = ...,
        t_max: _Bound = ...,
        max_hits: Optional[int] = ...,
    ) -> AllHits: ...
    def closest_point(self, points: npt.ArrayLike) -> Closest: ...
    def distance(self, points: npt.ArrayLike) -> npt.NDArray[np.float64]: ...
    def signed_distance(
        self, points: npt.ArrayLike, inside: _Inside = ...
    ) -> npt.NDArray[np.float64]: ...
    def contains(self, points: npt.ArrayLike, inside: _Inside = ...) -> npt.NDArray[np.bool_]: ...
    def winding_number(self, points: npt.ArrayLike) -> npt.NDArray[np.float64]: ...
    def _brute_force_all(
        self,
        origins: npt.ArrayLike,
        directions: npt.ArrayLike,
        t_min: _Bound = ...,
        t_max: _Bound = ...,
    ) -> AllHits: ...
    def to_bytes(self) -> bytes: ...
    def save(self, path: _Path) -> None: ...
    def __reduce__(self) -> tuple[Any, tuple[bytes]]: ...

@final
class Scene:
    """Several meshes, each placed as given and again by instances, in one kd-tree."""

    def __new__(cls) -> Scene: ...
    def __len__(self) -> int: ...
    def add_mesh(self, vertices: npt.ArrayLike, faces: npt.ArrayLike) -> int: ...
    def add_instance(self, mesh_id: int, transform: npt.ArrayLike) -> int: ...
    def build(
        self,
        preset: Optional[_Preset] = ...,
        algorithm: Optional[str] = ...,
        axes: Optional[str] = ...,
        counting: Optional[str] = ...,
        clip: Optional[bool] = ...,
        threads: Optional[int] = ...,
        bins: Optional[int] = ...,
        **cost: _Cost,
    ) -> None: ...
    def intersect(
        self,
        origins: npt.ArrayLike,
        directions: npt.ArrayLike,
        t_min: _Bound = ...,
        t_max: _Bound = ...,
        precision: _Precision = ...,
    ) -> SceneHits: ...
    def occluded(
        self,
        origins: npt.ArrayLike,
        directions: npt.ArrayLike,
        t_min: _Bound = ...,
        t_max: _Bound = ...,
        precision: _Precision = ...,
    ) -> npt.NDArray[np.bool_]: ...
    def closest_point(self, points: npt.ArrayLike) -> SceneClosest: ...
    def distance(self, points: npt.ArrayLike) -> npt.NDArray[np.float64]: ...
    def signed_distance(
        self, points: npt.ArrayLike, inside: _Inside = ...
    ) -> npt.NDArray[np.float64]: ...
    def contains(self, points: npt.ArrayLike, inside: _Inside = ...) -> npt.NDArray[np.bool_]: ...

def from_bytes(data: bytes) -> KdTree: ...
def load(path: _Path) -> KdTree: ...
def _read_mesh(path: _Path) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.int64]]: ...

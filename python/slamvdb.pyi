"""slamvdb: open-vocabulary semantic voxel maps (Python API over the C++ library).

Type stubs of the compiled module (python/module.cpp), installed beside it by
`cmake --install build --component python`. Arrays are numpy arrays; positions are in the world
frame (metres); poses are 4 x 4 T_world_sensor / T_world_camera matrices. Checked against the
module by CTest's Python.Install (mypy's stubtest).
"""
from os import PathLike
from typing import Any, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, PathLike[str]]

class Error(Exception):
    """A slamvdb error: a bad or unreadable file, a bad argument (the message names it)."""

class Map:
    """A semantic voxel map: free-floating submaps read through a global index (world frame)."""

    def __init__(
        self,
        voxel_size: float = 0.25,
        dim: int = 512,
        precision: str = "fp16",
        submap_length: float = 50.0,
        model_id: str = "",
    ) -> None:
        """An empty map: voxel edge (m), embedding dimension, storage precision ('fp16' or 'fp32'),
        metres of path per submap (0: one submap), the encoder whose embedding space it holds."""
    @property
    def voxel_size(self) -> float:
        """Voxel edge in metres."""
    @property
    def dim(self) -> int:
        """Embedding dimension."""
    @property
    def model_id(self) -> str:
        """The encoder whose embedding space the map holds."""
    @property
    def num_submaps(self) -> int:
        """Submaps in the map."""
    @property
    def num_semantic_voxels(self) -> int:
        """Semantic cells of the global index (world frame)."""
    def integrate_scan(self, stamp: float, points: npt.ArrayLike, T_world_sensor: npt.ArrayLike) -> dict[str, int]:
        """Integrate one LiDAR scan (N x 3 points in the sensor frame) at a pose; returns counts:
        points, dropped, hits, misses."""
    def fuse_features(
        self, stamp: float, features: npt.NDArray[Any], camera: dict[str, float], T_world_camera: npt.ArrayLike
    ) -> dict[str, Any]:
        """Fuse an H x W x C feature map (float16 fused as it is, other dtypes as float32) with the
        fusion rule the map records ('paper' for a new map); camera =
        {'fx', 'fy', 'cx', 'cy'} at the feature resolution. Returns fused, voxels, pixels_used,
        pixels_nonfinite, pixels_zero, feature_precision."""
    def finish(self) -> None:
        """Store the submap being written (call before saving)."""
    def save(self, path: _Path) -> None:
        """Write the map file (.svdb), atomically."""
    def semantic_voxels(
        self,
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float32], npt.NDArray[np.uint32]]:
        """(positions N x 3, embeddings N x dim, counts N), in cell order."""
    def statistics(self) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        """(weights N, spreads N) of the semantic voxels, in the order of semantic_voxels: the
        observations' summed weight (the count under the paper's rule) and their spread S/W (NaN for
        maps saved before format 3)."""
    def occupied_voxels(self) -> npt.NDArray[np.float64]:
        """Centres of the occupied world cells (all submaps combined), N x 3."""
    def search(
        self, query: npt.ArrayLike, top_k: int = 100, threshold: Optional[float] = None
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float32], npt.NDArray[np.uint32]]:
        """Cosine similarity with a query vector: (positions, scores, counts), best first."""
    def search_details(
        self,
        query: npt.ArrayLike,
        top_k: int = 100,
        threshold: Optional[float] = None,
        queries: Optional[QuerySet] = None,
        void_rule: bool = True,
        ignore_model_id: bool = False,
    ) -> dict[str, Any]:
        """search with what the map knows of each result, best first: dict of positions, scores,
        counts, weights, spreads (S/W; NaN where not known), and with queries also classes (-1:
        none), confidences (0..1, as classify gives them), names."""
    def classify(self, queries: QuerySet, void_rule: bool = True, ignore_model_id: bool = False) -> dict[str, Any]:
        """Label every semantic voxel with its most similar query (void takes its second-best with
        void_rule): dict of positions, classes, scores, margins, confidences (0..1), counts, names."""
    def at(self, points: npt.ArrayLike) -> dict[str, npt.NDArray[Any]]:
        """What the map holds at world points (N x 3): dict of found, counts, embeddings, weights,
        spreads (S/W; NaN where not found or not known)."""

def load_map(path: _Path) -> Map:
    """Load a map file (.svdb)."""

class QuerySet:
    """Named query vectors in one embedding space."""

    @staticmethod
    def load(path: _Path) -> QuerySet:
        """Load a query set file (.json, from train-queries or import-queries)."""
    @property
    def names(self) -> list[str]:
        """Class names, in order."""
    @property
    def model_id(self) -> str:
        """The encoder whose embedding space the vectors are in."""
    @property
    def vectors(self) -> npt.NDArray[np.float32]:
        """One query vector per class: classes x dim."""

def composite_query(
    positive: Sequence[npt.ArrayLike], negative: Sequence[npt.ArrayLike] = ...
) -> npt.NDArray[np.float32]:
    """sum(positive) - sum(negative), each term normalised, normalised (paper Figure 6.2)."""

def simulated_text_embedding(text: str, dim: int = 512, seed: int = 1) -> npt.NDArray[np.float32]:
    """Text embedding from the SIMULATED text encoder (the space of maps built with simulated
    features)."""

class TextEncoder:
    """A TorchScript CLIP text encoder (MODEL.pt with MODEL.json); only in builds with libtorch."""

    def __init__(self, path: _Path) -> None:
        """Load MODEL.pt (its manifest MODEL.json beside it)."""
    @property
    def model_id(self) -> str:
        """The model's embedding space."""
    def encode(self, text: str) -> npt.NDArray[np.float32]:
        """The text's embedding (dim)."""

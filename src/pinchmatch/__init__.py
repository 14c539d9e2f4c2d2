"""pinchmatch: thumb-index pinches that feel the same on a tangible prop and a virtual object.

Pipeline, one module per step::

    load        -> read a mesh file, convert to millimetres, repair, validate
    properties  -> centre of mass and principal axis
    surface     -> per-mesh context: dense surface sample, KD-tree, ray engine
    curvature   -> contact patches: normal and principal curvatures
    pinches     -> feasible pinch sampling and the feasibility rules
    features    -> the seven haptic features of the method
"""

from .errors import (
    ConfigError,
    ContactError,
    MeshError,
    NoFeasiblePinchError,
    PinchmatchError,
)
from .load import LoadedMesh, load_mesh
from .properties import ObjectProperties, object_properties
from .surface import SurfaceContext
from .curvature import PatchGeometry, patch_geometry
from .pinches import PinchSettings, Pinches, check_pinches
from .sampling import sample_pinches
from .features import PinchFeatures, pinch_features

__version__ = "0.1.0"

__all__ = [
    "ConfigError",
    "ContactError",
    "MeshError",
    "NoFeasiblePinchError",
    "PinchmatchError",
    "LoadedMesh",
    "load_mesh",
    "ObjectProperties",
    "object_properties",
    "SurfaceContext",
    "PatchGeometry",
    "patch_geometry",
    "PinchSettings",
    "Pinches",
    "sample_pinches",
    "check_pinches",
    "PinchFeatures",
    "pinch_features",
    "__version__",
]

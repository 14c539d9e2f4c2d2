"""pinchmatch: thumb-index pinches that feel the same on a tangible prop and a virtual object.

The package is laid out as the pipeline, one subpackage per stage; a stage imports only the stages
above it in this list (checked in CI by import-linter, ``[tool.importlinter]`` in pyproject.toml)::

    errors, files    the errors every stage raises; the one writer of files (whole or not at all)
    mesh/            load (read, convert to mm, repair, validate), level (a glTF scene's mesh
                     nodes), manifest (per-object options from TOML), regions (where fingers may
                     touch), properties (centre of mass, principal axis), surface (sample, KD-tree,
                     rays), shapes and vessels (analytic and hollow test objects)
    grasp/           hand (what a hand reaches), curvature and jets (contact patches), pinches (the
                     rules), sampling and spread (where to pinch), features (the seven haptic
                     features), analysis (one object, end to end)
    match/           cost (criteria, JNDs), candidates (one object's poses), register (the rigid
                     placement), reference (the paper's Ref), search (the exact best pairs)
    export/          documents (JSON, CSV), scenes (glTF), figures (PNG), view (the page and its
                     server), folder (publishing OUT whole), sink (a run's results as they come)
    runner/          cache (features on disk), worker, tasks and executors (parallel and Dask),
                     matching (a whole run), study (the paper's user study: ``pinchmatch demo``)
    cli/             parser (every option and its bounds), commands (the command line), console
                     (progress and tables)

The public API, importable from ``pinchmatch`` itself (resolved on first use, so that importing the
package stays cheap):

- loading and properties: :func:`load_mesh` -> :class:`LoadedMesh`; :func:`object_properties` ->
  :class:`ObjectProperties`; :class:`SurfaceContext`;
- manifests and levels: :func:`read_manifest` and :func:`object_specs` -> :class:`ObjectSpec` s
  (per-object units, up, centre of mass, axis, mass, regions; a level's nodes);
- pinches: :class:`PinchSettings`; :func:`sample_pinches`, :func:`check_pinches` ->
  :class:`Pinches`; :func:`patch_geometry` -> :class:`PatchGeometry`; :func:`pinch_features` ->
  :class:`PinchFeatures`;
- one object end to end: :func:`analyze_object` (a file), :func:`analyze_prop` (a prop standing on
  its table, as the command line reads props) or :func:`analyze_spec` (an
  :class:`ObjectSpec`) -> :class:`ObjectAnalysis`; :func:`find_pinches`;
  :func:`score_pinches` (given poses);
- matching: :func:`candidate_poses` -> :class:`Candidates`; :class:`MatchSettings`; the run's one
  configuration :class:`Config` (pinch and match settings, with a digest); the one match
  :func:`match_one` (one virtual object -> :class:`VirtualMatch` holding :class:`Choice` s, each
  with its two :class:`Pose` s); :func:`match_scene` -> :class:`SceneMatch`, one per virtual object;
  one virtual object as a scene: :func:`match_virtual`; given pose pairs:
  :func:`evaluate_pairs` -> :class:`PairResult`;
- registration: :func:`register_poses`, :func:`register_pose` (the rigid placement of a pose pair),
  :func:`rotations_between`;
- the cost: :class:`CostModel` (criteria, JNDs, pooling, read-only :class:`Weights` completed by
  :func:`complete_weights`), :func:`cost_model` (a run's);
- a shelf of props: :func:`select_props` -> :class:`Selection`, :func:`coverage_curve`;
  :func:`design_props` (:class:`DesignSettings`) -> :class:`DesignResult`;
- weights from people's ratings: :func:`read_ratings` -> :class:`Ratings`
  (:func:`fittable_criteria`: the criteria a table can determine), :func:`calibrate` ->
  :class:`Calibration`, :func:`read_weights_file` (what ``calibrate`` wrote);
- errors: :class:`PinchmatchError` and its kinds :class:`ConfigError` (a bad argument, option or
  options file), :class:`MeshError`, :class:`ContactError`, :class:`NoFeasiblePinchError`,
  :class:`OutputError`; a broken invariant of pinchmatch's own (a bug) raises
  :class:`InternalError`.
"""

from importlib import import_module
from typing import TYPE_CHECKING

from .version import __version__

#: public name -> the module that defines it
_API = {
    "ConfigError": "errors", "ContactError": "errors", "InternalError": "errors",
    "MeshError": "errors", "NoFeasiblePinchError": "errors", "OutputError": "errors",
    "PinchmatchError": "errors", "LoadedMesh": "mesh.load", "load_mesh": "mesh.load",
    "ObjectProperties": "mesh.properties", "object_properties": "mesh.properties",
    "SurfaceContext": "mesh.surface",
    "ObjectSpec": "mesh.manifest", "object_specs": "mesh.manifest",
    "read_manifest": "mesh.manifest", "rotations_between": "mesh.frames",
    "PatchGeometry": "grasp.curvature", "patch_geometry": "grasp.curvature",
    "PinchSettings": "grasp.pinches", "Pinches": "grasp.pinches", "check_pinches": "grasp.pinches",
    "sample_pinches": "grasp.sampling",
    "PinchFeatures": "grasp.features", "pinch_features": "grasp.features",
    "ObjectAnalysis": "grasp.analysis", "analyze_object": "grasp.analysis",
    "analyze_spec": "grasp.analysis", "analyze_prop": "grasp.analysis",
    "find_pinches": "grasp.analysis", "score_pinches": "grasp.analysis",
    "CostModel": "match.cost", "Weights": "match.cost", "complete_weights": "match.cost",
    "Candidates": "match.candidates", "candidate_poses": "match.candidates",
    "register_pose": "match.register", "register_poses": "match.register",
    "Choice": "match.search", "MatchSettings": "match.search", "PairResult": "match.search",
    "cost_model": "match.search", "evaluate_pairs": "match.search",
    "SceneMatch": "match.scene", "VirtualMatch": "match.scene", "match_scene": "match.scene",
    "match_virtual": "match.scene", "match_one": "match.scene", "Config": "config",
    "Pose": "match.search", "Selection": "match.select", "coverage_curve": "match.select",
    "select_props": "match.select", "Calibration": "match.calibrate", "Ratings": "match.calibrate",
    "calibrate": "match.calibrate", "read_ratings": "match.calibrate",
    "read_weights_file": "match.calibrate", "fittable_criteria": "match.calibrate",
    "DesignResult": "runner.design", "DesignSettings": "runner.design",
    "design_props": "runner.design", "Scan": "scan.read", "read_scan": "scan.read",
    "Imported": "scan.prop_import", "import_prop": "scan.prop_import",
}

if TYPE_CHECKING:  # what static tools see; at run time each name is imported on first use
    from .errors import (
        ConfigError, ContactError, InternalError, MeshError, NoFeasiblePinchError, OutputError,
        PinchmatchError,
    )
    from .mesh.load import LoadedMesh, load_mesh
    from .mesh.properties import ObjectProperties, object_properties
    from .mesh.surface import SurfaceContext
    from .mesh.manifest import ObjectSpec, object_specs, read_manifest
    from .mesh.frames import rotations_between
    from .grasp.curvature import PatchGeometry, patch_geometry
    from .grasp.pinches import PinchSettings, Pinches, check_pinches
    from .grasp.sampling import sample_pinches
    from .grasp.features import PinchFeatures, pinch_features
    from .grasp.analysis import (ObjectAnalysis, analyze_object, analyze_prop, analyze_spec,
                                 find_pinches, score_pinches)
    from .match.cost import CostModel, Weights, complete_weights
    from .match.candidates import Candidates, candidate_poses
    from .match.register import register_pose, register_poses
    from .match.search import Choice, MatchSettings, PairResult, Pose, cost_model, evaluate_pairs
    from .config import Config
    from .match.scene import SceneMatch, VirtualMatch, match_one, match_scene, match_virtual
    from .match.select import Selection, coverage_curve, select_props
    from .match.calibrate import (Calibration, Ratings, calibrate, fittable_criteria, read_ratings,
                                  read_weights_file)
    from .runner.design import DesignResult, DesignSettings, design_props
    from .scan.read import Scan, read_scan
    from .scan.prop_import import Imported, import_prop

__all__ = sorted(_API) + ["__version__"]


def __getattr__(name: str):
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'pinchmatch' has no attribute {name!r}")
    value = getattr(import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))

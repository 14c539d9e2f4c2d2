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
- pinches: :class:`PinchSettings`; :func:`sample_pinches`, :func:`check_pinches` -> :class:`Pinches`;
  :func:`patch_geometry` -> :class:`PatchGeometry`; :func:`pinch_features` -> :class:`PinchFeatures`;
- one object end to end: :func:`analyze_object` (a file) or :func:`analyze_spec` (an
  :class:`ObjectSpec`) -> :class:`ObjectAnalysis`; :func:`find_pinches`;
  :func:`score_pinches` (given poses);
- matching: :func:`candidate_poses` -> :class:`Candidates`; :class:`MatchSettings`;
  :func:`match_scene` -> :class:`SceneMatch` (per virtual object a :class:`VirtualMatch` holding
  :class:`Choice` s);
- errors: :class:`PinchmatchError` and its kinds :class:`ConfigError`, :class:`MeshError`,
  :class:`ContactError`, :class:`NoFeasiblePinchError`.
"""

from importlib import import_module

from .version import __version__

#: public name -> the module that defines it
_API = {
    "ConfigError": "errors", "ContactError": "errors", "MeshError": "errors",
    "NoFeasiblePinchError": "errors", "PinchmatchError": "errors",
    "LoadedMesh": "mesh.load", "load_mesh": "mesh.load",
    "ObjectProperties": "mesh.properties", "object_properties": "mesh.properties",
    "SurfaceContext": "mesh.surface",
    "ObjectSpec": "mesh.manifest", "read_manifest": "mesh.manifest", "object_specs": "mesh.manifest",
    "PatchGeometry": "grasp.curvature", "patch_geometry": "grasp.curvature",
    "PinchSettings": "grasp.pinches", "Pinches": "grasp.pinches", "check_pinches": "grasp.pinches",
    "sample_pinches": "grasp.sampling",
    "PinchFeatures": "grasp.features", "pinch_features": "grasp.features",
    "ObjectAnalysis": "grasp.analysis", "analyze_object": "grasp.analysis", "find_pinches": "grasp.analysis",
    "analyze_spec": "grasp.analysis",
    "score_pinches": "grasp.analysis",
    "Candidates": "match.candidates", "candidate_poses": "match.candidates",
    "MatchSettings": "match.search", "match_scene": "match.scene", "SceneMatch": "match.scene",
    "VirtualMatch": "match.scene", "Choice": "match.search",
}

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

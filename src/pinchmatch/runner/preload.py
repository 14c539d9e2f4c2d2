"""What the fork server of local workers loads before it forks any
(:mod:`pinchmatch.runner.forkserver`).

Importing this module imports every module a task runs and compiles (or loads from numba's cache)
the loader's topology kernels, by repairing a small sphere, and the patch-fit, neighbour and spread
kernels, by sampling a few pinches on it and fitting a cluster of patches: each worker forked
afterwards has them ready. A failure here is only logged: the worker then loads what it needs
itself, and any real error shows in its task.
"""

from __future__ import annotations

import logging

import numpy as np

from . import tasks  # noqa: F401  (the whole pipeline a task runs)

log = logging.getLogger(__name__)


def warm_kernels() -> None:
    """Run the compiled kernels once, on one thread, so that they are loaded in this process."""
    from ..cores import set_thread_budget
    from ..grasp.pinches import PinchSettings
    from ..mesh import topology
    from ..grasp.curvature import patch_geometry
    from ..grasp.sampling import sample_pinches
    from ..mesh.lowest import lowest_along, lowest_table
    from ..mesh.neighbours import CLUSTER_POINTS
    from ..mesh.shapes import sphere
    from ..mesh.surface import SurfaceContext

    before = set_thread_budget(1)
    try:
        mesh = sphere(30.0, faces=320).mesh
        vertices, faces = mesh.vertices, mesh.faces
        topology.merge_vertices(vertices, faces, 8)
        topology.nondegenerate_faces(vertices, faces, 1e-9)
        topology.unique_faces(faces)
        topology.thickness(vertices)
        e = topology.edges(faces)
        topology.component_labels(topology.face_adjacency(e), len(faces))
        topology.signed_volumes(vertices, faces)
        context = SurfaceContext(mesh)
        sample_pinches(context, settings=PinchSettings(count=8, seed=0))
        lowest_along(lowest_table(vertices), mesh.vertex_normals[:4])  # the rest gaps' kernel
        # a cluster's kernel
        patch_geometry(context, np.repeat(vertices[:1], CLUSTER_POINTS, axis=0),
                       np.repeat(mesh.vertex_normals[:1], CLUSTER_POINTS, axis=0))
    except Exception as exc:  # noqa: BLE001 - a warm-up: the worker's own task shows any real error
        log.debug("warming the kernels failed: %s", exc)
    finally:
        set_thread_budget(before)


warm_kernels()

"""Stage 1, the mesh: read a file into millimetres and a clean, closed (or knowingly open)
surface; its centre of mass and principal axis; the surface context every later stage queries
(a dense sample, a KD-tree, a ray engine). Also the analytic and hollow objects of the tests."""

"""Meshes of an LDI (paper, Section 3.4).

``types`` holds :class:`~photo3d.mesh.types.Mesh` and
:class:`~photo3d.mesh.types.TexturedMesh`; ``full`` builds the vertex-coloured mesh
(one vertex per LDI pixel), ``light`` the textured one simplified to an error
bound (``_charts``, ``_planar``, ``_simplify`` and its kernels ``_collapse`` are its
parts).
"""

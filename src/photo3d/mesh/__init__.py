"""Meshes of an LDI (paper, Section 3.4).

``full`` builds the vertex-coloured :class:`~photo3d.structures.mesh.Mesh` (one vertex
per LDI pixel), ``light`` the :class:`~photo3d.structures.mesh.TexturedMesh` simplified
to an error bound (``_charts``, ``_planar``, ``_simplify`` and its kernels ``_collapse``
are its parts). The types live in :mod:`photo3d.structures`.
"""

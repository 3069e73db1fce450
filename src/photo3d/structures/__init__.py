"""The types that cross layers, below every layer that uses them.

============  ==============================================================
module        types
============  ==============================================================
``ldi``       :class:`~photo3d.structures.ldi.LDI`, the layered depth image (built by
              :mod:`photo3d.stages.ldi`)
``mesh``      :class:`~photo3d.structures.mesh.Mesh` and
              :class:`~photo3d.structures.mesh.TexturedMesh` (built by :mod:`photo3d.mesh`)
``patch``     :class:`~photo3d.structures.patch.Patch` and
              :class:`~photo3d.structures.patch.InpaintResult` (cut by
              :mod:`photo3d.stages.patches`, filled by :mod:`photo3d.inpaint`)
============  ==============================================================

They hold data and check it; they build nothing and import only the foundations
(:mod:`photo3d.camera`, :mod:`photo3d.errors`).
"""

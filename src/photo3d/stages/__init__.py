"""The pipeline's stages, in the order data flows (paper, Section 3).

==============  ===========================================================
module          stage
==============  ===========================================================
``preprocess``  photo + disparity -> working size, filtered disparity, its steps
                on the photo's colour edges, linked depth edges (with
                ``filters``, ``align`` and ``edges``)
``ldi``         the layered depth image, cut along the depth edges
``border``      the lattice extended past the frame
``regions``     per edge: synthesis and context regions
``patches``     regions -> the inpainter's image-like patches
(``inpaint``)   a backend fills each patch (:mod:`photo3d.inpaint`)
``merge``       filled pixels joined to the LDI; new edges for the next pass
==============  ===========================================================

Each stage is a pure function with a typed result; :func:`photo3d.pipeline.make`
wires them and holds no algorithm. ``docs/architecture.md`` draws the whole tree.
"""

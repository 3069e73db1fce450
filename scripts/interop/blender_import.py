"""Run the README's Blender import steps headlessly on a ``mesh.glb`` and check them.

Runs with Blender's Python module (``bpy``, not a photo3d dependency), in its own
environment, e.g.::

    python3.11 -m venv /tmp/bpyvenv && /tmp/bpyvenv/bin/pip install bpy==4.2.0
    /tmp/bpyvenv/bin/python scripts/interop/blender_import.py out/demo/mesh.glb shot.png

What it does, as the README says a user would: import the GLB with Blender's glTF
importer; find the camera object ``input view`` and make it the scene camera; set
the render resolution from the mesh's custom properties (glTF ``extras``); render
one frame (Cycles on the CPU, ``--scale`` of the photo's size) to the PNG. It
prints what it found as JSON (objects, camera field of view, texture size, material
nodes, render time) and exits non-zero if the camera or the texture is missing.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("glb")
    parser.add_argument("png")
    parser.add_argument("--scale", type=int, default=50, help="render size, percent")
    parser.add_argument("--samples", type=int, default=4)
    parser.add_argument("--shift", default="0,0,0",
                        help="camera move in Blender units (x right, y up, z back)")
    args = parser.parse_args()
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    t = time.perf_counter()
    bpy.ops.import_scene.gltf(filepath=args.glb)
    import_s = time.perf_counter() - t
    objects = {o.name: o.type for o in bpy.data.objects}
    camera = bpy.data.objects.get("input view")
    meshes = [o for o in bpy.data.objects if o.type == "MESH"]
    report = {"blender": bpy.app.version_string, "objects": objects, "import_s": import_s}
    if camera is None or camera.type != "CAMERA" or not meshes:
        print(json.dumps(report, indent=2))
        sys.exit("no camera object 'input view' or no mesh imported")
    mesh = meshes[0]
    extras = {k: mesh.data.get(k, mesh.get(k)) for k in ("width", "height", "hfov", "vfov")}
    images = [(i.name, list(i.size)) for i in bpy.data.images]
    material = mesh.active_material
    nodes = sorted({n.bl_idname for n in material.node_tree.nodes}) if material else []
    report.update(
        triangles=sum(len(p.vertices) - 2 for p in mesh.data.polygons),
        extras=extras, images=images, material=material.name if material else None,
        material_nodes=nodes, camera_location=list(camera.location),
        camera_looks_along=[round(v, 6) for v in camera.matrix_world.to_3x3().col[2] * -1],
        camera_sensor_fit=camera.data.sensor_fit,
    )
    if not images or "ShaderNodeTexImage" not in nodes:
        print(json.dumps(report, indent=2))
        sys.exit("the texture did not come in")
    scene = bpy.context.scene
    scene.camera = camera
    width, height = int(extras["width"] or 0), int(extras["height"] or 0)
    if width and height:
        scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = args.scale
    shift = [float(v) for v in args.shift.split(",")]
    camera.location = [a + b for a, b in zip(camera.location, (shift[0], -shift[2], shift[1]),
                                             strict=True)]
    report["camera_vertical_fov_deg"] = math.degrees(camera.data.angle_y)
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = args.samples
    scene.view_settings.view_transform = "Standard"  # the texture is the photo: no filmic
    scene.render.filepath = args.png
    t = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    report["render_s"] = time.perf_counter() - t
    report["render_size"] = [scene.render.resolution_x * args.scale // 100,
                             scene.render.resolution_y * args.scale // 100]
    print(json.dumps(report, indent=2), flush=True)
    os._exit(0)  # bpy 4.2 may crash while tearing down at interpreter exit


if __name__ == "__main__":
    main()

# Run by scripts/blender-check inside Blender: blender -b --python scripts/blender_check.py --
# GLB VDB JPG. Imports the glTF (with Debian's Blender 3.4 workaround, import_shading='SMOOTH')
# and the OpenVDB volume, checks them against the GLB's own JSON and renders the JPEG.
import json
import struct
import sys

import bpy
from mathutils import Vector

glb, vdb, image = sys.argv[sys.argv.index("--") + 1:]


def glb_tubes(path):
    """The tube mesh's triangle count and radius, from the GLB's JSON (nothing of Blender's)."""
    data = open(path, "rb").read()
    length, = struct.unpack_from("<I", data, 12)
    doc = json.loads(data[20:20 + length])
    tubes = next(m for m in doc["meshes"] if m["name"] == "tubes")
    triangles = sum(doc["accessors"][p["indices"]]["count"] // 3 for p in tubes["primitives"])
    return triangles, tubes["extras"]["linebake_tube_radius"]


def world_box(objects):
    corners = [o.matrix_world @ Vector(c) for o in objects for c in o.bound_box]
    lo = Vector([min(c[i] for c in corners) for i in range(3)])
    hi = Vector([max(c[i] for c in corners) for i in range(3)])
    return lo, hi


bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=glb, import_shading="SMOOTH")
meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
bpy.ops.object.volume_import(filepath=vdb, files=[{"name": vdb.rsplit("/", 1)[-1]}],
                             directory=vdb.rsplit("/", 1)[0] + "/")
volumes = [o for o in bpy.context.scene.objects if o.type == "VOLUME"]
failures = []
if len(meshes) != 1 or len(volumes) != 1:
    failures.append(f"{len(meshes)} mesh objects and {len(volumes)} volumes, expected 1 and 1")
triangles = sum(len(p.vertices) - 2 for o in meshes for p in o.data.polygons)
expected, radius = glb_tubes(glb)
if triangles != expected:
    failures.append(f"{triangles} triangles in Blender, {expected} in the GLB")
colours = [a.name for o in meshes for a in o.data.color_attributes]
if not colours:
    failures.append("the tubes carry no colour attribute (COLOR_0)")
volume = volumes[0]
grids = volume.data.grids
grids.load()
names = sorted(g.name for g in grids)
mesh_lo, mesh_hi = world_box(meshes)
vol_lo, vol_hi = world_box(volumes)
# The volume's box spans its voxels' centres, the mesh's reaches a tube radius past the lines:
# each face of one box within a voxel and a radius of the other's.
voxel = grids[0].matrix_object[0][0]
tolerance = voxel + radius
offsets = [abs(mesh_lo[i] - vol_lo[i]) for i in range(3)] + [abs(mesh_hi[i] - vol_hi[i]) for i in range(3)]
agreement = max(offsets)
if agreement > tolerance:
    failures.append(f"the boxes differ by {agreement:.3f} (more than a voxel and a radius, "
                    f"{tolerance:.3f}): mesh {mesh_lo[:]}..{mesh_hi[:]}, volume {vol_lo[:]}..{vol_hi[:]}")
print(f"blender_check: {len(meshes)} mesh, {len(volumes)} volume (grids {names}), {triangles} "
      f"triangles (GLB {expected}), colour attributes {colours}, boxes mesh "
      f"{tuple(round(x, 3) for x in mesh_lo)}..{tuple(round(x, 3) for x in mesh_hi)} volume "
      f"{tuple(round(x, 3) for x in vol_lo)}..{tuple(round(x, 3) for x in vol_hi)}, "
      f"largest face offset {agreement:.3f} (a voxel and a radius: {tolerance:.3f})")

# The picture: the tubes in their COLOR_0 colours beside a faint volume, from the front-left.
scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.samples = 32
scene.cycles.use_denoising = False  # Debian's Blender is built without OpenImageDenoise
scene.render.resolution_x, scene.render.resolution_y = 960, 540
scene.render.film_transparent = False
world = bpy.data.worlds.new("world")
world.use_nodes = True
world.node_tree.nodes["Background"].inputs[0].default_value = (0.02, 0.02, 0.025, 1)
scene.world = world
volume.hide_render = True  # the tubes alone: the volume would veil them
centre = (mesh_lo + mesh_hi) / 2
size = max(mesh_hi - mesh_lo)
camera = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
scene.collection.objects.link(camera)
camera.location = centre + Vector((-1.1, -1.7, 0.9)) * size
camera.rotation_euler = (centre - camera.location).to_track_quat("-Z", "Y").to_euler()
scene.camera = camera
sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
sun.data.energy = 3
sun.rotation_euler = (0.7, 0.2, -0.6)
scene.collection.objects.link(sun)
scene.render.image_settings.file_format = "JPEG"  # a tenth of the PNG's bytes
scene.render.image_settings.quality = 88
scene.render.filepath = image
bpy.ops.render.render(write_still=True)
print(f"blender_check: rendered {image}")
if failures:
    print("blender_check: FAILED: " + "; ".join(failures))
    sys.exit(1)
print("blender_check: passed")

# Imports a Blot .glb in Blender (headless) and checks what an artist gets:
# the vertex count, the stain as a colour attribute, and the baked colour and
# roughness (wetness) textures on the material. Run as
#   blender -b --factory-startup --python-exit-code 1 -P gltf_blender_check.py -- FILE.glb VERTICES TEXTURE_SIZE
# Exit code 1 (an uncaught exception) on any mismatch.
import sys

import bpy
import numpy

# Debian 12's Blender 3.4 glTF importer uses numpy.bool, which Debian's numpy
# 1.24 removed (AttributeError in set_poly_smoothing); restore the alias.
if not hasattr(numpy, "bool"):
    numpy.bool = bool

args = sys.argv[sys.argv.index("--") + 1:]
path, vertices, texture_size = args[0], int(args[1]), int(args[2])

bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=path)

meshes = {o.name: o.data for o in bpy.data.objects if o.type == "MESH"}
print("blender: imported objects", sorted(meshes))
# Both glTF scenes are imported: the textured mesh and the vertex-colour mesh.
textured = [m for m in meshes.values() if m.uv_layers]
colored = [m for m in meshes.values() if m.color_attributes]
assert textured, "no imported mesh has UVs"
assert colored, "no imported mesh has a colour attribute"
for mesh in list(meshes.values()):
    assert len(mesh.vertices) == vertices, f"{mesh.name}: {len(mesh.vertices)} vertices, expected {vertices}"

# The colour attribute holds the stain: not all one colour, within [0, 1].
attribute = colored[0].color_attributes[0]
values = [tuple(d.color[:3]) for d in attribute.data]
assert len(values) in (vertices, 3 * len(colored[0].polygons)), f"colour attribute has {len(values)} entries"
assert all(0.0 <= c <= 1.0 for v in values for c in v), "colour outside [0, 1]"
darkest = min(sum(v) for v in values)
lightest = max(sum(v) for v in values)
assert lightest - darkest > 0.05, f"colour attribute is uniform ({darkest:.3f}..{lightest:.3f}): no stain"

# The textured mesh's material samples the baked texture.
material = textured[0].materials[0]
assert material is not None and material.use_nodes, "textured mesh has no node material"
# Two image textures: the stain colour (sRGB) and the wetness as roughness
# (glTF's metallicRoughness texture, imported as Non-Color data).
images = [n.image for n in material.node_tree.nodes if n.type == "TEX_IMAGE" and n.image is not None]
assert images, f"material {material.name} has no image texture"
spaces = {image.colorspace_settings.name: image for image in images}
assert "sRGB" in spaces, f"no sRGB image texture (colour spaces {sorted(spaces)})"
color = spaces["sRGB"]
width, height = color.size
assert (width, height) == (texture_size, texture_size), f"texture is {width}x{height}, expected {texture_size}"
assert "Non-Color" in spaces, f"no Non-Color image texture for the roughness (colour spaces {sorted(spaces)})"
bsdf = [n for n in material.node_tree.nodes if n.type == "BSDF_PRINCIPLED"]
assert bsdf and bsdf[0].inputs["Roughness"].is_linked, "the roughness is not driven by a texture"
print(f"blender: OK: {vertices} vertices, colour attribute '{attribute.name}' ({darkest:.3f}..{lightest:.3f}),"
      f" texture {width}x{height} sRGB, roughness texture {spaces['Non-Color'].size[0]}x{spaces['Non-Color'].size[1]} Non-Color")

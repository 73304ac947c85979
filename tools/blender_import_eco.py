"""Import an eco scene into Blender from the files of `eco instance` (docs/export.md).

    eco instance out/demo/scene.h5 --prototypes 8 --out out/demo/blender
    blender --python tools/blender_import_eco.py -- out/demo/blender

(or open this file in Blender's Scripting workspace, set DIRECTORY below and press Run).

What it builds (Blender 3.2 or later, for the Named Attribute node; written against the 3.x and
4.x Python API; run in Blender 3.4.1 by the CTest blender_import, tests/blender, which
checks every plant's instance and is skipped where Blender is not installed):
* a hidden collection "eco prototypes" with one placeholder object per row of
  prototypes.csv: a cone of the prototype's height and crown radius, standing on its base,
  in its species' colour. Replace them by real plant models (keep the names, which keep
  the order: proto_00000, proto_00001, ...);
* an object "eco plants": one vertex per plant of instances.ply (world metres, minus the
  offset printed below so that Blender's float precision holds for large coordinates), with
  the point attributes `prototype`, `rotation` (radians about z), `scale`, `species`, `layer`,
  the offset as custom properties eco_offset_x_m, eco_offset_y_m (world = local + offset),
  and a Geometry Nodes modifier that puts an instance of its prototype on every point
  (Instance on Points, pick instance by `prototype`, rotated and scaled): hundreds of
  thousands of instances stay light because they share the prototypes' meshes;
* an object "eco ground": the terrain (terrain.exr) as a grid mesh, one vertex per cell
  centre, whose material mixes soil, litter and grass by the forest floor densities
  (images "eco litter" and "eco grass" from litter.exr and grass.exr, float, non-colour).

The readers below need only numpy (Blender ships it) and are tested outside Blender
(tests/python/test_ecotoolkit.py, TestExportFor3D): read_ply, read_exr, read_csv.
"""

import csv
import math
import os
import struct
import sys

import numpy as np

DIRECTORY = ""  # when run from Blender's text editor: the folder given to `eco instance --out`

_PLY_TYPES = {"char": "i1", "uchar": "u1", "short": "<i2", "ushort": "<u2", "int": "<i4", "uint": "<u4",
              "float": "<f4", "double": "<f8", "int8": "i1", "uint8": "u1", "int16": "<i2", "uint16": "<u2",
              "int32": "<i4", "uint32": "<u4", "float32": "<f4", "float64": "<f8"}


def read_ply(path):
    """The vertex element of a binary little-endian PLY (as eco writes it) as a numpy
    structured array, and the header's comment lines."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    if header[0] != "ply" or header[1] != "format binary_little_endian 1.0":
        raise ValueError(f"{path}: not a binary little-endian PLY file")
    fields, count, comments, in_vertex = [], 0, [], False
    for line in header[2:]:
        words = line.split()
        if words[0] == "comment":
            comments.append(line[len("comment "):])
        elif words[0] == "element":
            in_vertex = words[1] == "vertex"
            if in_vertex:
                count = int(words[2])
            elif int(words[2]) > 0:
                raise ValueError(f"{path}: only a vertex element is read, found '{line}'")
        elif words[0] == "property" and in_vertex:
            if words[1] == "list":
                raise ValueError(f"{path}: list properties are not read")
            fields.append((words[2], _PLY_TYPES[words[1]]))
    dtype = np.dtype(fields)
    vertices = np.frombuffer(data, dtype=dtype, count=count, offset=end)
    return vertices, comments


def read_exr(path):
    """A single-channel, uncompressed, scanline 32-bit float OpenEXR (as eco writes it) as a
    2-D numpy array (row 0 = the northern row) and its header attributes (strings as str)."""
    with open(path, "rb") as f:
        data = f.read()
    if struct.unpack_from("<I", data, 0)[0] != 20000630:
        raise ValueError(f"{path}: not an OpenEXR file")
    pos, attrs = 8, {}
    while data[pos] != 0:
        name_end = data.index(b"\0", pos)
        name = data[pos:name_end].decode()
        type_end = data.index(b"\0", name_end + 1)
        kind = data[name_end + 1:type_end].decode()
        size = struct.unpack_from("<i", data, type_end + 1)[0]
        value = data[type_end + 5:type_end + 5 + size]
        if kind == "string":
            attrs[name] = value.decode()
        elif kind == "box2i":
            attrs[name] = struct.unpack("<4i", value)
        elif kind == "compression":
            attrs[name] = value[0]
        elif kind == "chlist":
            channels, p = [], 0
            while value[p] != 0:
                e = value.index(b"\0", p)
                channels.append((value[p:e].decode(), struct.unpack_from("<i", value, e + 1)[0]))
                p = e + 1 + 16
            attrs[name] = channels
        else:
            attrs[name] = value
        pos = type_end + 5 + size
    pos += 1  # end of header
    x0, y0, x1, y1 = attrs["dataWindow"]
    width, height = x1 - x0 + 1, y1 - y0 + 1
    if attrs.get("compression") != 0 or len(attrs["channels"]) != 1 or attrs["channels"][0][1] != 2:
        raise ValueError(f"{path}: only uncompressed single-channel float images are read")
    offsets = struct.unpack_from(f"<{height}Q", data, pos)
    image = np.empty((height, width), dtype=np.float32)
    for offset in offsets:  # each chunk: row (int32), byte count (int32), the row's floats
        row, size = struct.unpack_from("<ii", data, offset)
        image[row - y0] = np.frombuffer(data, dtype="<f4", count=width, offset=offset + 8)
    return image, attrs


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


# ----------------------------------------------------------------------------- Blender part

def _species_colours(vertices):
    colours = {}
    for s, r, g, b in zip(vertices["species"], vertices["red"], vertices["green"], vertices["blue"]):
        colours.setdefault(int(s), (r / 255.0, g / 255.0, b / 255.0, 1.0))
    return colours


def _material(bpy, name, colour):
    m = bpy.data.materials.get(name) or bpy.data.materials.new(name)
    m.diffuse_color = colour
    m.use_nodes = True
    bsdf = m.node_tree.nodes.get("Principled BSDF")
    if bsdf:
        bsdf.inputs["Base Color"].default_value = colour
    return m


def _group_socket(group, name, in_out, kind):
    if hasattr(group, "interface"):  # Blender 4
        group.interface.new_socket(name=name, in_out=in_out, socket_type=kind)
    elif in_out == "INPUT":  # Blender 3
        group.inputs.new(kind, name)
    else:
        group.outputs.new(kind, name)


def _output(node, name):
    """The node's output `name` that is in use: Blender 3.x's Named Attribute node has one
    "Attribute" output per data type, only the one of its data_type enabled (outputs[name]
    would give the first, a float vector, whatever the type); Blender 4 has one."""
    for socket in node.outputs:
        if socket.name == name and socket.enabled:
            return socket
    raise KeyError(f"{node.name}: no enabled output '{name}'")


def _instancing_nodes(bpy, collection):
    group = bpy.data.node_groups.new("eco instances", "GeometryNodeTree")
    _group_socket(group, "Geometry", "INPUT", "NodeSocketGeometry")
    _group_socket(group, "Geometry", "OUTPUT", "NodeSocketGeometry")
    n = group.nodes
    gin, gout = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
    info = n.new("GeometryNodeCollectionInfo")
    info.inputs["Collection"].default_value = collection
    info.inputs["Separate Children"].default_value = True
    info.inputs["Reset Children"].default_value = True
    inst = n.new("GeometryNodeInstanceOnPoints")
    inst.inputs["Pick Instance"].default_value = True
    attr = {}
    for name, kind in (("prototype", "INT"), ("rotation", "FLOAT"), ("scale", "FLOAT")):
        a = n.new("GeometryNodeInputNamedAttribute")
        a.data_type = kind
        a.inputs["Name"].default_value = name
        attr[name] = a
    euler = n.new("ShaderNodeCombineXYZ")
    links = group.links
    links.new(gin.outputs[0], inst.inputs["Points"])
    links.new(info.outputs[0], inst.inputs["Instance"])
    links.new(_output(attr["prototype"], "Attribute"), inst.inputs["Instance Index"])
    links.new(_output(attr["rotation"], "Attribute"), euler.inputs["Z"])
    links.new(euler.outputs[0], inst.inputs["Rotation"])
    links.new(_output(attr["scale"], "Attribute"), inst.inputs["Scale"])
    links.new(inst.outputs[0], gout.inputs[0])
    return group


def build(directory):
    import bpy  # only inside Blender

    vertices, comments = read_ply(os.path.join(directory, "instances.ply"))
    prototypes = read_csv(os.path.join(directory, "prototypes.csv"))
    colours = _species_colours(vertices)
    offset = np.array([float(vertices["x"].min()), float(vertices["y"].min()), 0.0])
    print(f"eco: {len(vertices)} plants, {len(prototypes)} prototypes; offset x {offset[0]:.3f} m, y {offset[1]:.3f} m")

    protos = bpy.data.collections.new("eco prototypes")
    bpy.context.scene.collection.children.link(protos)
    for row in prototypes:
        pid, species = int(row["prototype"]), int(row["species_id"])
        h, r = float(row["height_m"]), float(row["crown_radius_m"])
        mesh = bpy.data.meshes.new(f"proto_{pid:05d}")
        # A cone standing on its base: 16 segments, radius r, height h.
        verts = [(r * math.cos(2 * math.pi * k / 16), r * math.sin(2 * math.pi * k / 16), 0.0) for k in range(16)]
        verts.append((0.0, 0.0, h))
        faces = [(k, (k + 1) % 16, 16) for k in range(16)] + [tuple(range(15, -1, -1))]
        mesh.from_pydata(verts, [], faces)
        mesh.materials.append(_material(bpy, f"eco {row['species']}", colours.get(species, (0.5, 0.5, 0.5, 1.0))))
        obj = bpy.data.objects.new(f"proto_{pid:05d}", mesh)
        protos.objects.link(obj)
    protos.hide_render = True
    bpy.context.view_layer.layer_collection.children[protos.name].exclude = True

    points = bpy.data.meshes.new("eco plants")
    xyz = np.stack([vertices["x"] - offset[0], vertices["y"] - offset[1], vertices["z"]], axis=1).astype(np.float32)
    points.vertices.add(len(vertices))
    points.vertices.foreach_set("co", xyz.ravel())
    for name, kind, values in (("prototype", "INT", vertices["prototype"].astype(np.int32)),
                               ("species", "INT", vertices["species"].astype(np.int32)),
                               ("layer", "INT", vertices["layer"].astype(np.int32)),
                               ("rotation", "FLOAT", np.radians(vertices["rotation_deg"]).astype(np.float32)),
                               ("scale", "FLOAT", vertices["scale"].astype(np.float32))):
        a = points.attributes.new(name, kind, "POINT")
        a.data.foreach_set("value", values)
    plants = bpy.data.objects.new("eco plants", points)
    plants["eco_offset_x_m"], plants["eco_offset_y_m"] = float(offset[0]), float(offset[1])  # world = local + offset
    bpy.context.scene.collection.objects.link(plants)
    modifier = plants.modifiers.new("eco instances", "NODES")
    modifier.node_group = _instancing_nodes(bpy, protos)

    # The ground: terrain.exr as a grid mesh (a vertex at each cell centre), with the forest
    # floor densities (grass.exr, litter.exr) as non-colour images mixed into its material.
    terrain_path = os.path.join(directory, "terrain.exr")
    if os.path.exists(terrain_path):
        elevation, attrs = read_exr(terrain_path)
        rows, cols = elevation.shape
        cell = float(attrs["eco:cell_size_m"])
        x0, y0 = float(attrs["eco:origin_x_m"]) - offset[0], float(attrs["eco:origin_y_m"]) - offset[1]
        i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")  # image row i: north first
        verts = np.stack([x0 + (j + 0.5) * cell, y0 + (rows - 1 - i + 0.5) * cell, elevation], axis=-1).reshape(-1, 3)
        k = (i[:-1, :-1] * cols + j[:-1, :-1]).ravel()
        faces = np.stack([k + cols, k + cols + 1, k + 1, k], axis=1)  # counter-clockwise seen from above
        mesh = bpy.data.meshes.new("eco ground")
        mesh.from_pydata(verts.tolist(), [], faces.tolist())
        uv = mesh.uv_layers.new(name="UVMap")
        loops_vertex = faces.ravel()
        u = (loops_vertex % cols + 0.5) / cols
        v = 1.0 - (loops_vertex // cols + 0.5) / rows  # Blender's v = 0 is the image's last (southern) row
        uv.data.foreach_set("uv", np.stack([u, v], axis=1).astype(np.float32).ravel())
        mat = bpy.data.materials.new("eco ground")
        mat.use_nodes = True
        nodes, links = mat.node_tree.nodes, mat.node_tree.links
        bsdf = nodes.get("Principled BSDF")
        colour = None
        soil, litter_brown, grass_green = (0.25, 0.18, 0.1, 1.0), (0.42, 0.3, 0.16, 1.0), (0.2, 0.45, 0.12, 1.0)
        for name, tint in (("litter", litter_brown), ("grass", grass_green)):
            exr = os.path.join(directory, f"{name}.exr")
            if not os.path.exists(exr):
                continue
            img = bpy.data.images.load(exr)
            img.name = f"eco {name}"
            img.colorspace_settings.name = "Non-Color"
            tex = nodes.new("ShaderNodeTexImage")
            tex.image = img
            mix = nodes.new("ShaderNodeMixRGB")  # density 0: what is below; 1: the tint
            links.new(tex.outputs["Color"], mix.inputs["Fac"])
            if colour is None:
                mix.inputs["Color1"].default_value = soil
            else:
                links.new(colour, mix.inputs["Color1"])
            mix.inputs["Color2"].default_value = tint
            colour = mix.outputs["Color"]
        if bsdf and colour is not None:
            links.new(colour, bsdf.inputs["Base Color"])
        mesh.materials.append(mat)
        ground = bpy.data.objects.new("eco ground", mesh)
        bpy.context.scene.collection.objects.link(ground)
    # The comments of the PLY header name the scene and the species.
    for c in comments:
        print("eco:", c)


if __name__ == "__main__":
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    directory = argv[0] if argv else DIRECTORY
    if not directory:
        sys.exit("usage: blender --python tools/blender_import_eco.py -- DIRECTORY (the folder of eco instance --out)")
    build(directory)

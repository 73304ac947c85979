"""Run inside Blender after tools/blender_import_eco.py (tests/blender/run.py, docs/export.md):

    blender --background --factory-startup --python-exit-code 1 \
        --python tools/blender_import_eco.py --python tests/blender/check_import.py -- DIR OUT.blend

checks the scene the recipe built against the files of `eco instance` in DIR, saves it as
OUT.blend, opens the saved file and checks it again. Prints "blender check: ok ..." or raises
(exit code 1 with --python-exit-code 1) with the failures.
"""

import csv
import importlib.util
import math
import os
import sys

import bpy

argv = sys.argv[sys.argv.index("--") + 1:]
DIRECTORY, BLEND = argv[0], argv[1]

spec = importlib.util.spec_from_file_location(
    "blender_import_eco", os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tools", "blender_import_eco.py"))
recipe = importlib.util.module_from_spec(spec)
spec.loader.exec_module(recipe)


def read_csv(name):
    with open(os.path.join(DIRECTORY, name), newline="") as f:
        return list(csv.DictReader(f))


plants = read_csv("instances.csv")
prototypes = read_csv("prototypes.csv")
elevation, exr = recipe.read_exr(os.path.join(DIRECTORY, "terrain.exr"))


def check(label):
    failures = []

    def expect(ok, what):
        if not ok and len(failures) < 20:
            failures.append(what)

    protos = bpy.data.collections.get("eco prototypes")
    expect(protos is not None, "no collection 'eco prototypes'")
    names = sorted(o.name for o in protos.objects) if protos else []
    expect(names == [f"proto_{i:05d}" for i in range(len(prototypes))],
           f"prototype objects {names[:3]}... ({len(names)}), expected {len(prototypes)} named proto_00000...")
    for row in prototypes:
        obj = bpy.data.objects.get(f"proto_{int(row['prototype']):05d}")
        if obj is None:
            continue
        top = max(v.co.z for v in obj.data.vertices)
        radius = max(math.hypot(v.co.x, v.co.y) for v in obj.data.vertices)
        expect(abs(top - float(row["height_m"])) < 1e-4 and abs(radius - float(row["crown_radius_m"])) < 1e-4,
               f"{obj.name}: height {top}, radius {radius}, expected {row['height_m']}, {row['crown_radius_m']}")

    obj = bpy.data.objects.get("eco plants")
    expect(obj is not None, "no object 'eco plants'")
    if obj is None:
        return failures, 0
    expect(len(obj.data.vertices) == len(plants), f"eco plants: {len(obj.data.vertices)} points, expected {len(plants)}")
    offset_x, offset_y = obj["eco_offset_x_m"], obj["eco_offset_y_m"]

    # The evaluated scene: one instance per plant, of its prototype, at its place, turned and scaled.
    depsgraph = bpy.context.evaluated_depsgraph_get()
    seen = 0
    worst = 0.0
    for inst in depsgraph.object_instances:
        if not inst.is_instance or inst.parent is None or inst.parent.name != "eco plants":
            continue
        i = inst.persistent_id[0]  # the point's index: the plant's row (id) in instances.csv
        seen += 1
        if i >= len(plants):
            expect(False, f"instance of point {i}: beyond the {len(plants)} plants")
            continue
        p = plants[i]
        expect(inst.object.name == f"proto_{int(p['prototype']):05d}",
               f"plant {i}: instance of {inst.object.name}, expected prototype {p['prototype']}")
        m = inst.matrix_world
        t = m.translation
        error = max(abs(t.x + offset_x - float(p["x_m"])), abs(t.y + offset_y - float(p["y_m"])),
                    abs(t.z - float(p["ground_z_m"])))
        worst = max(worst, error)
        expect(error < 1e-3, f"plant {i}: at ({t.x + offset_x}, {t.y + offset_y}, {t.z}), expected ({p['x_m']}, {p['y_m']}, {p['ground_z_m']})")
        scale = m.to_scale()
        expect(max(abs(s - float(p["scale"])) for s in scale) < 1e-5 * max(1.0, float(p["scale"])),
               f"plant {i}: scale {tuple(scale)}, expected {p['scale']}")
        angle = m.to_euler().z
        want = math.radians(float(p["rotation_deg"]))
        expect(abs(math.cos(angle) - math.cos(want)) < 1e-4 and abs(math.sin(angle) - math.sin(want)) < 1e-4,
               f"plant {i}: rotated {math.degrees(angle)} deg, expected {p['rotation_deg']}")
    expect(seen == len(plants), f"{seen} plant instances, expected {len(plants)}")

    ground = bpy.data.objects.get("eco ground")
    expect(ground is not None, "no object 'eco ground'")
    if ground is not None:
        rows, cols = elevation.shape
        verts = ground.data.vertices
        expect(len(verts) == rows * cols, f"eco ground: {len(verts)} vertices, expected {rows} x {cols}")
        cell = float(exr["eco:cell_size_m"])
        for k in (0, cols - 1, len(verts) // 2, len(verts) - 1):  # vertex k: image row k // cols (north first)
            i, j = divmod(k, cols)
            x = float(exr["eco:origin_x_m"]) + (j + 0.5) * cell
            y = float(exr["eco:origin_y_m"]) + (rows - 1 - i + 0.5) * cell
            v = verts[k].co
            expect(abs(v.x + offset_x - x) < 1e-3 and abs(v.y + offset_y - y) < 1e-3 and abs(v.z - elevation[i, j]) < 1e-4,
                   f"eco ground vertex {k}: {tuple(v)}, expected ({x}, {y}, {elevation[i, j]}) less the offset")
        mat = ground.data.materials[0] if ground.data.materials else None
        images = sorted(n.image.name for n in mat.node_tree.nodes if n.type == "TEX_IMAGE") if mat else []
        expect(images == ["eco grass", "eco litter"], f"eco ground's images {images}")
        for name in images:
            expect(bpy.data.images[name].colorspace_settings.name == "Non-Color", f"{name}: not Non-Color")
    print(f"blender check ({label}): {seen} plant instances of {len(names)} prototypes, largest position error {worst:.2e} m")
    return failures, seen


failures, seen = check("imported")
if not failures:
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(BLEND))
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(BLEND))
    failures, seen = check("saved and reopened")
if failures:
    raise AssertionError("blender check failed:\n  " + "\n  ".join(failures))
print(f"blender check: ok, {seen} plants, {len(prototypes)} prototypes, saved {BLEND}")

"""Tests of python/ecotoolkit against real eco outputs (issue 31 item 2).

setUpModule runs the eco binary (ECO_BINARY, else build/apps/eco) on a tiny scene whose
terrain is an ESRI ASCII grid written here with a known origin and cell size, then each
reader's result is checked against a path that does not go through the package: that
grid's own numbers, the CSV the same command writes, the counts eco prints or
`eco inspect` reports, the generator's parameters, and brute-force pair counts. About 5 s.
Run: PYTHONPATH=python ECO_BINARY=build/apps/eco /usr/bin/python3 -m unittest discover -s tests/python -v
"""

import contextlib
import csv
import io
import os
import re
import shutil
import subprocess
import tempfile
import unittest

import h5py
import numpy as np

import ecotoolkit as eco

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
ECO = os.path.abspath(os.environ.get("ECO_BINARY") or os.path.join(ROOT, "build", "apps", "eco"))

# The scene: a generated terrain re-based to a known origin and cell size.
NX, NY, CELL, X0, Y0 = 60, 45, 0.8, 500.0, 1000.0
# On cell edges of the grid (8 and 58 columns, 8 and 44 rows), so that every simulated plant
# lies in a cell whose centre is inside the window, and in the database region.
CROP = (X0 + 8 * CELL, Y0 + 8 * CELL, X0 + 58 * CELL, Y0 + 44 * CELL)
YEARS, SNAPSHOT_EVERY = 4, 2

D = None          # temporary directory of the outputs
LOG = {}          # what each eco command printed
ASC = None        # the terrain we wrote: header and north-first rows


def run_eco(name, *args):
    r = subprocess.run([ECO, "--threads", "2", *args], cwd=D, capture_output=True, text=True, timeout=120)
    if r.returncode != 0:
        raise RuntimeError(f"eco {' '.join(args)} failed ({r.returncode}):\n{r.stdout}\n{r.stderr}")
    LOG[name] = r.stdout + r.stderr
    return LOG[name]


def read_asc(path):
    """An ESRI ASCII grid read by hand: header dict and rows, first row = northern."""
    with open(path) as f:
        lines = f.read().split("\n")
    keys = ("ncols", "nrows", "xllcorner", "yllcorner", "cellsize", "nodata_value")
    header, n = {}, 0
    while lines[n].split() and lines[n].split()[0].lower() in keys:
        key, value = lines[n].split()
        header[key.lower()] = float(value)
        n += 1
    rows = np.array([[float(v) for v in line.split()] for line in lines[n:] if line.strip()])
    return header, rows


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def setUpModule():
    global D, ASC
    if not os.access(ECO, os.X_OK):
        raise unittest.SkipTest(f"no eco binary at {ECO} (set ECO_BINARY)")
    D = tempfile.mkdtemp(prefix="ecotoolkit-test-")
    # A generated terrain as .asc, re-based: origin (X0, Y0), cell CELL.
    run_eco("generate", "terrain", "generate", "--out", "generated.asc", "--width", str(NX), "--height", str(NY),
            "--cell-size", "1", "--seed", "4")
    with open(os.path.join(D, "generated.asc")) as f:
        body = [line for line in f.read().split("\n")
                if line.strip() and line.split()[0].lower() not in ("ncols", "nrows", "xllcorner", "yllcorner",
                                                                      "cellsize", "nodata_value")]
    with open(os.path.join(D, "input.asc"), "w") as f:
        f.write(f"ncols {NX}\nnrows {NY}\nxllcorner {X0}\nyllcorner {Y0}\ncellsize {CELL}\n" + "\n".join(body) + "\n")
    ASC = read_asc(os.path.join(D, "input.asc"))
    run_eco("convert", "terrain", "convert", "input.asc", "terrain.h5")
    run_eco("chm", "chm", "generate", "--terrain", "terrain.h5", "--out", "chm.h5", "--seed", "2", "--sketch-seed", "3")
    run_eco("abiotics", "abiotics", "--terrain", "terrain.h5", "--out", "abiotics.h5", "--sun-step", "60")
    run_eco("canopy", "canopy", "--terrain", "terrain.h5", "--chm", "chm.h5", "--abiotics", "abiotics.h5",
            "--out", "canopy.h5", "--csv", "canopy.csv")
    run_eco("simulate", "simulate", "--abiotics", "abiotics.h5", "--canopy", "canopy.h5", "--terrain", "terrain.h5",
            "--crop", ",".join(f"{v:g}" for v in CROP), "--years", str(YEARS), "--seed", "5",
            "--snapshot-years", str(SNAPSHOT_EVERY), "--out", "sim.h5", "--csv", "sim.csv")
    # The same window with a fire in year 1 and a storm in year 2 (docs/disturbance.md): the
    # events' burn and damage masks.
    with open(os.path.join(D, "fire.toml"), "w") as f:
        f.write('[inputs]\nabiotics = "abiotics.h5"\ncanopy = "canopy.h5"\nterrain = "terrain.h5"\n'
                f'[run]\nyears = 3\nseed = 5\ncrop = [{", ".join(f"{v:g}" for v in CROP)}]\n'
                'snapshot_years = [0, 1, 2, 3]\n[outputs]\nhdf5 = "fire.h5"\n'
                '[disturbance.fire]\nyears = [1]\nspread_probability = 0.45\nseverity = 1.0\nscorch_height_m = 1000.0\n'
                '[disturbance.storm]\nyears = [2]\nseverity = 1.0\nreference_height_m = 0.05\n')
    run_eco("simulate fire", "simulate", "--config", "fire.toml")
    # Disturbance configured, no event in the run: the file's event tables are empty.
    with open(os.path.join(D, "quiet.toml"), "w") as f:
        f.write('[inputs]\nabiotics = "abiotics.h5"\ncanopy = "canopy.h5"\nterrain = "terrain.h5"\n'
                f'[run]\nyears = 1\nseed = 5\ncrop = [{", ".join(f"{v:g}" for v in CROP)}]\n'
                '[outputs]\nhdf5 = "quiet.h5"\n[disturbance.fire]\nyears = [40]\n')
    run_eco("simulate quiet", "simulate", "--config", "quiet.toml")
    run_eco("analyse", "analyse", "sim.h5", "--out", "db.h5", "--kmax", "3")
    run_eco("inspect", "inspect", "db.h5")
    run_eco("synth", "synth", "--terrain", "terrain.h5", "--canopy", "canopy.h5", "--database", "db.h5",
            "--abiotics", "abiotics.h5", "--out", "scene.h5", "--csv", "scene.csv")


def tearDownModule():
    if D and not os.environ.get("ECO_KEEP_TEST_FILES"):
        shutil.rmtree(D, ignore_errors=True)


def path(name):
    return os.path.join(D, name)


class GridGeometry:
    """Checks a Grid against the ASCII grid we wrote."""

    def assert_on_input_grid(self, g):
        header, _ = ASC
        self.assertEqual(g.values.shape[-2:], (int(header["nrows"]), int(header["ncols"])))
        self.assertAlmostEqual(g.cell_size_m, header["cellsize"])
        self.assertAlmostEqual(g.x[0], header["xllcorner"] + 0.5 * header["cellsize"])
        self.assertAlmostEqual(g.x[-1], header["xllcorner"] + (header["ncols"] - 0.5) * header["cellsize"])
        self.assertAlmostEqual(g.y[0], header["yllcorner"] + 0.5 * header["cellsize"])
        self.assertAlmostEqual(g.y[-1], header["yllcorner"] + (header["nrows"] - 0.5) * header["cellsize"])
        np.testing.assert_allclose(g.extent, (X0, X0 + NX * CELL, Y0, Y0 + NY * CELL))


class TestGridText(unittest.TestCase):
    def test_a_utm_origin_is_printed_in_full(self):
        # It printed "from (546000, 4.26e+06)": a northing rounded to 10 km.
        g = eco.Grid(np.zeros((2, 3), dtype=np.float32), 1.0, 546000.0, 4260300.0, "m", name="/terrain/elevation")
        self.assertIn("from (546000, 4260300)", repr(g))


class TestTerrain(unittest.TestCase, GridGeometry):
    def test_values_and_coordinates_match_the_ascii_grid(self):
        t = eco.read_terrain(path("terrain.h5"))
        self.assertEqual((t.format, t.schema_version), ("eco-terrain", 1))
        self.assert_on_input_grid(t.elevation)
        self.assertEqual(t.elevation.units, "m")
        _, rows = ASC
        # The .asc lists the northern row first; the package keeps the file's south-first rows.
        np.testing.assert_allclose(t.elevation.values, rows[::-1], rtol=1e-6)
        np.testing.assert_allclose(t.elevation.north_up(), rows, rtol=1e-6)
        # A point in the north-east corner cell: last column, first .asc row.
        x, y = X0 + NX * CELL - 0.1, Y0 + NY * CELL - 0.1
        self.assertAlmostEqual(float(t.elevation.at(x, y)), rows[0, -1], places=4)
        self.assertEqual(t.elevation.cell_of(X0 + 2.5 * CELL, Y0 + 1.5 * CELL), (2, 1))
        with self.assertRaises(ValueError):
            t.elevation.at(X0 - 1, Y0)

    def test_converted_back_to_ascii_gives_the_same_numbers(self):
        run_eco("convert_back", "terrain", "convert", "terrain.h5", "back.asc")
        header, rows = read_asc(path("back.asc"))
        t = eco.open(path("terrain.h5"))
        self.assertIsInstance(t, eco.Terrain)
        self.assertAlmostEqual(header["xllcorner"], t.elevation.origin_x_m)
        np.testing.assert_allclose(t.elevation.north_up(), rows, rtol=1e-6)


class TestChm(unittest.TestCase, GridGeometry):
    def test_chm_geometry_trees_and_printed_summary(self):
        c = eco.read_chm(path("chm.h5"))
        self.assertEqual(c.format, "eco-chm")
        self.assert_on_input_grid(c.height)
        self.assert_on_input_grid(c.sketch)
        # CF units since issue 31 (docs/hdf5.md); what the value is, in long_name.
        self.assertEqual(c.height.units, "m")
        self.assertEqual(c.height.attrs["long_name"], "canopy height above ground")
        # "wrote CHM: chm.h5 (...; 60 x 45 cells of 0.8 m, 0 .. 39.6953 m above ground, 31 trees)"
        m = re.search(r"(\d+) x (\d+) cells of ([\d.]+) m, ([\d.]+) \.\. ([\d.]+) m above ground, (\d+) trees", LOG["chm"])
        self.assertIsNotNone(m, LOG["chm"])
        self.assertEqual(c.height.values.shape, (int(m[2]), int(m[1])))
        self.assertAlmostEqual(float(c.height.values.max()), float(m[5]), delta=1e-3)
        self.assertEqual(len(c.trees["x_m"]), int(m[6]))
        self.assertEqual(c.tree_units["height_m"], "m")
        self.assertTrue(set(np.unique(c.sketch.values)) <= {0, 1, 2})
        self.assertEqual((c.generator["seed"], c.sketch.attrs["seed"]), (2, 3))
        # The trees lie on the terrain's extent.
        x0, x1, y0, y1 = c.height.extent
        self.assertTrue(np.all((c.trees["x_m"] >= x0) & (c.trees["x_m"] <= x1)))
        self.assertTrue(np.all((c.trees["y_m"] >= y0) & (c.trees["y_m"] <= y1)))


class TestAbiotics(unittest.TestCase, GridGeometry):
    def test_maps_months_units(self):
        a = eco.read_abiotics(path("abiotics.h5"))
        self.assertEqual(a.format, "eco-abiotics")
        _, rows = ASC
        np.testing.assert_allclose(a.elevation.values, rows[::-1], rtol=1e-6)
        expected_units = {"elevation": "m", "slope": "degrees", "sun": "hours/day", "moisture": "mm/month",
                          "temperature": "degC", "wind": "m/s"}
        for name, units in expected_units.items():
            g = a.grids[name]
            self.assert_on_input_grid(g)
            self.assertEqual(g.units, units, name)
        # "wrote abiotics: abiotics.h5 (/elevation, /slope, /sun [12][45][60] hours/day, ...)"
        m = re.search(r"/sun \[(\d+)\]\[(\d+)\]\[(\d+)\]", LOG["abiotics"])
        self.assertEqual(a.sun.values.shape, tuple(int(v) for v in m.groups()))
        np.testing.assert_array_equal(a.sun.months, np.arange(1, 13))
        self.assertEqual(a.sun.month(6).values.shape, (NY, NX))
        np.testing.assert_allclose(a.sun.month(6).values, a.sun.values[5])
        np.testing.assert_allclose(a.temperature.annual_mean().values, a.temperature.values.mean(axis=0))
        self.assertEqual(a.sun.at(X0 + 1, Y0 + 1).shape, (12,))
        # Sun hours cannot exceed the day length of the month (the generator's own bound).
        day = np.asarray(a.attrs["sun_day_length_hours"])
        self.assertTrue(np.all(a.sun.values <= day[:, None, None] + 1e-4))
        self.assertTrue(np.all(a.sun.values >= 0))
        self.assertTrue(np.all((a.slope.values >= 0) & (a.slope.values <= 90)))
        self.assertEqual(a.schema_version, 2)
        self.assertTrue(np.all((a.wind.values >= 0) & (a.wind.values <= a.attrs["wind_strength_m_s"] + 1e-6)))


class TestCanopy(unittest.TestCase, GridGeometry):
    def test_trees_match_the_csv(self):
        c = eco.read_canopy(path("canopy.h5"))
        self.assertIn(c.schema_version, (1, 2))
        rows = read_csv(path("canopy.csv"))
        m = re.search(r"placed (\d+) canopy trees", LOG["canopy"])
        self.assertEqual(len(c.trees), int(m[1]))
        self.assertEqual(len(c.trees), len(rows))
        np.testing.assert_array_equal(c.trees["species"], [r["species"] for r in rows])
        np.testing.assert_array_equal(c.trees["species_id"], [int(r["species_id"]) for r in rows])
        for field, column in (("x", "x_m"), ("y", "y_m"), ("ground_z", "ground_z_m"), ("height", "height_m"),
                              ("crown_radius", "crown_radius_m")):
            np.testing.assert_allclose(c.trees[field], [float(r[column]) for r in rows], atol=6e-4, err_msg=field)
            self.assertEqual(c.trees.units[field], "m")
        for g in (c.species_map, c.chm, c.terrain):
            self.assert_on_input_grid(g)
        ids = np.unique(c.species_map.values)
        self.assertTrue(np.all((ids == -1) | ((ids >= 0) & (ids < len(c.trees.species_names)))))
        self.assertEqual(c.trees.counts(), {name: sum(r["species"] == name for r in rows)
                                            for name in {r["species"] for r in rows}})
        self.assertEqual(int(c.iterations["trees"][-1]), len(rows))


class TestDisturbanceMasks(unittest.TestCase):
    def test_fire_mask_holds_no_survivor_and_the_killed_plants(self):
        s = eco.read_simulation(path("fire.h5"))
        self.assertEqual([(e.kind, e.year) for e in s.disturbances], [("fire", 1), ("storm", 2)])
        self.assertEqual(eco.read_simulation(path("sim.h5")).disturbances, [])  # no disturbance configured
        self.assertEqual(eco.read_simulation(path("quiet.h5")).disturbances, [])  # configured, no event
        fire = s.disturbances[0]
        self.assertEqual(fire.mask.dtype, bool)
        cells = int(fire.mask.sum())
        self.assertGreater(cells, 0)
        # Its area: the struck cells' area clipped to the simulated window.
        x0, y0 = fire.mask_extent[0], fire.mask_extent[1]
        cy, cx = np.nonzero(fire.mask)
        ax0 = np.maximum(x0 + cx * fire.mask_cell_m, s.window_m[0])
        ax1 = np.minimum(x0 + (cx + 1) * fire.mask_cell_m, s.window_m[2])
        ay0 = np.maximum(y0 + cy * fire.mask_cell_m, s.window_m[1])
        ay1 = np.minimum(y0 + (cy + 1) * fire.mask_cell_m, s.window_m[3])
        self.assertAlmostEqual(float(np.sum(np.clip(ax1 - ax0, 0, None) * np.clip(ay1 - ay0, 0, None))), fire.area_m2,
                               places=6)
        # The fire (year 1, August) kills every plant of a burnt cell (severity 1, scorch above
        # all): a plant of the census before it (year 1) still alive in the next (year 2) stands
        # outside the mask, and plants before it inside the mask are gone.
        before, after = s.snapshots[1], s.snapshots[2]
        survived = np.isin(before["id"], after["id"])
        inside = fire.mask_contains(before["x"], before["y"])
        self.assertGreater(int(inside.sum()), 0)
        self.assertGreater(int(survived.sum()), 0)
        self.assertEqual(int((survived & inside).sum()), 0)
        # A storm's mask: cells in which a plant was thrown (killed_total > 0 then).
        storm = s.disturbances[1]
        self.assertEqual(storm.mask.shape, fire.mask.shape)
        self.assertEqual(int(storm.mask.any()), int(storm.killed_total > 0))


class TestSimulation(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.s = eco.read_simulation(path("sim.h5"))
        cls.rows = read_csv(path("sim.csv"))

    def test_final_snapshot_matches_the_csv(self):
        s, rows = self.s, self.rows
        m = re.search(r"(\d+) plants at the end", LOG["simulate"])
        self.assertEqual(len(s.final), int(m[1]))
        self.assertEqual(len(s.final), len(rows))
        p = s.final
        np.testing.assert_array_equal(p["id"], [int(r["id"]) for r in rows])
        self.assertEqual(p["id"].dtype, np.int64)
        np.testing.assert_array_equal(p["species"], [r["species"] for r in rows])
        for field, column, tol in (("x", "x_m", 6e-5), ("y", "y_m", 6e-5), ("height", "height_m", 6e-6),
                                   ("crown_radius", "crown_radius_m", 6e-6), ("age", "age_years", 6e-5),
                                   ("growth_age", "growth_age_years", 6e-7), ("vigour", "vigour", 6e-7),
                                   ("pool", "pool", 6e-7)):
            np.testing.assert_allclose(p[field], [float(r[column]) for r in rows], atol=tol, err_msg=field)
        self.assertEqual((p.units["x"], p.units["age"], p.units["sun_share"], p.units["water_share"]),
                         ("m", "years", "hours/day", "mm/month"))

    def test_snapshot_years_window_and_census(self):
        s, rows = self.s, self.rows
        self.assertEqual(s.years, list(range(SNAPSHOT_EVERY, YEARS + 1, SNAPSHOT_EVERY)))
        np.testing.assert_allclose(s.window_m, CROP)
        for p in s.snapshots.values():
            self.assertTrue(np.all((p["x"] >= CROP[0]) & (p["x"] <= CROP[2])))
            self.assertTrue(np.all((p["y"] >= CROP[1]) & (p["y"] <= CROP[3])))
        c = s.census
        np.testing.assert_array_equal(c.years, np.arange(0, YEARS + 1))
        self.assertEqual(c.count.shape, (YEARS + 1, len(c.species_names)))
        self.assertEqual((c.units["count"], c.units["mean_height"], c.units["crown_area"]), ("1", "m", "m2"))
        # The final year's census against the CSV of the final plants.
        for i, name in enumerate(c.species_names):
            heights = [float(r["height_m"]) for r in rows if r["species"] == name]
            self.assertEqual(int(c.count[-1, i]), len(heights), name)
            if heights:
                self.assertAlmostEqual(c.mean_height[-1, i], np.mean(heights), delta=1e-5, msg=name)
                radii = np.array([float(r["crown_radius_m"]) for r in rows if r["species"] == name])
                self.assertAlmostEqual(c.crown_area[-1, i], np.sum(np.pi * radii ** 2), delta=1e-3 * len(radii))
        # and a snapshot year's census against that snapshot's table.
        year = s.years[0]
        counts = s.snapshots[year].counts()
        row = list(c.years).index(year)
        for i, name in enumerate(c.species_names):
            self.assertEqual(int(c.count[row, i]), counts.get(name, 0))
        self.assertEqual(len(s.canopy), len(eco.read_canopy(path("canopy.h5")).trees))


class TestDatabase(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.db = eco.read_database(path("db.h5"))
        cls.inspect = LOG["inspect"]

    def test_summary_matches_eco_inspect(self):
        db, text = self.db, self.inspect
        m = re.search(r"format (\S+), schema (\d+)", text)
        self.assertEqual((db.format, db.schema_version), (m[1].rstrip(","), int(m[2])))
        m = re.search(r"(\d+) species, (\d+) sub-biomes", text)
        self.assertEqual((len(db.species_names), len(db.sub_biome_names)), (int(m[1]), int(m[2])))
        self.assertEqual(len(db.categories), 2 * len(db.species_names))
        m = re.search(r"pair correlation: (\d+) bins of ([\d.]+) m to ([\d.]+) m", text)
        nb, width, rmax = int(m[1]), float(m[2]), float(m[3])
        self.assertEqual(len(db.pcf_r_m), nb)
        np.testing.assert_allclose(db.pcf_r_m, (np.arange(nb) + 0.5) * width)
        self.assertAlmostEqual(db.bins["pcf_edges_m"][-1], rmax)
        m = re.search(r"combinations: (\d+), regions: (\d+)", text)
        self.assertEqual((len(db.combinations["mask"]), db.n_regions), (int(m[1]), int(m[2])))
        self.assertEqual(len(db.inputs), int(re.search(r"inputs: (\d+)", text)[1]))
        for m in re.finditer(r"region (\d+) \(cluster (\d+)\): ([\d.]+) m2, (\d+) plants, ([\d.]+) plants/m2", text):
            i = int(m[1])
            r = db.region(i)
            self.assertEqual(r.cluster, int(m[2]))
            self.assertAlmostEqual(db.regions["area_m2"][i], float(m[3]), delta=0.5)
            self.assertEqual(int(db.regions["undergrowth_count"][i]), int(m[4]))
            self.assertAlmostEqual(db.regions["density_per_m2"][i], float(m[5]), delta=1e-4)
        leading = re.search(r"leading species: (.*?); (\d+) species pairs", text)
        for name, pct in re.findall(r"([A-Za-z' -]+?) ([\d.]+)%", leading[1]):
            i = db.species_names.index(name.strip())
            self.assertAlmostEqual(100 * db.regions["species_proportion"][0, i], float(pct), delta=0.051)
        self.assertEqual(len(db.region(0).pairs["source"]), int(leading[2]))
        self.assertEqual(db.region_units["density_per_m2"], "m-2")  # UDUNITS (plants per m^2)
        self.assertEqual(db.feature_units, ["hours/day", "mm", "degC", "degrees", "m/s"])

    def test_pair_counts_against_brute_force_on_the_simulation_csv(self):
        # One region covers the whole simulated window here (eco inspect: 0 plants in no region).
        self.assertIn("0 plants in no region", self.inspect)
        rows = read_csv(path("sim.csv"))
        db = self.db
        edges = db.bins["pcf_edges_m"]
        counts = db.region(0).pairs
        names = [db.categories["name"][c] for c in (counts["source"][0], counts["target"][0])]
        for source, target in ((names[0], names[1]), ("Toyon", "Toyon"), ("Toyon", "Tanoak")):
            if source not in db.categories["name"] or target not in db.categories["name"]:
                continue
            p = np.array([(float(r["x_m"]), float(r["y_m"])) for r in rows if r["species"] == source])
            q = np.array([(float(r["x_m"]), float(r["y_m"])) for r in rows if r["species"] == target])
            if len(p) == 0 or len(q) == 0:
                continue
            d = np.hypot(p[:, None, 0] - q[None, :, 0], p[:, None, 1] - q[None, :, 1])
            if source == target:
                np.fill_diagonal(d, np.inf)  # ordered pairs of distinct plants
            brute, _ = np.histogram(d[np.isfinite(d)], bins=edges)
            r_m, stored = db.pcf(0, source, target, "pair_count")
            np.testing.assert_allclose(r_m, db.pcf_r_m)
            # Positions in the CSV are rounded to 0.1 mm: a few pairs move across a bin edge.
            self.assertLessEqual(np.abs(brute - stored).sum(), 1e-3 * stored.sum() + 2, (source, target))
            self.assertGreater(stored.sum(), 0)
        # g is the documented ratio of the stored sums (docs/database.md).
        pairs = db.region(0).pairs
        denom = db.bins["pcf_annulus_area_m2"][None, :] * pairs["normalisation_per_m2"][:, None]
        expected = np.where(denom > 0, pairs["translate_weighted"] / np.where(denom > 0, denom, 1), 0)
        np.testing.assert_allclose(pairs["g"], expected, rtol=1e-9, atol=1e-12)
        table = db.pcf_table(0)
        self.assertEqual(len(table), len(pairs["source"]) * len(db.pcf_r_m))
        r_m, g = db.pcf(0, "Toyon", "Toyon") if "Toyon" in pairs["source_name"] else db.pcf(0, names[0], names[1])
        self.assertEqual(len(g), len(r_m))
        with self.assertRaises(KeyError):
            db.category("No Such Species")


class TestScene(unittest.TestCase, GridGeometry):
    def test_plants_match_the_csv_and_grids_the_terrain(self):
        s = eco.read_scene(path("scene.h5"))
        rows = read_csv(path("scene.csv"))
        m = re.search(r"canopy trees: (\d+); undergrowth plants: (\d+)", LOG["synth"])
        self.assertEqual((len(s.canopy), len(s.undergrowth)), (int(m[1]), int(m[2])))
        allp = s.plants()
        self.assertEqual(len(allp), len(rows))
        np.testing.assert_array_equal(allp["layer"], [r["layer"] for r in rows])
        np.testing.assert_array_equal(allp["species"], [r["species"] for r in rows])
        for field, column in (("x", "x_m"), ("y", "y_m"), ("height", "height_m"), ("crown_radius", "crown_radius_m")):
            np.testing.assert_allclose(allp[field], [float(r[column]) for r in rows], atol=6e-4, err_msg=field)
        for g in (s.grass, s.litter, s.cluster_map, s.combination_map, s.terrain):
            self.assert_on_input_grid(g)
        _, asc_rows = ASC
        np.testing.assert_allclose(s.terrain.values, asc_rows[::-1], rtol=1e-6)
        for g in (s.grass, s.litter):
            self.assertEqual(g.units, "1")  # dimensionless (CF); "density, 0..1" in long_name
            self.assertIn("density, 0..1", g.attrs["long_name"])
            self.assertTrue(np.all((g.values >= 0) & (g.values <= 1)))
        self.assertEqual(int(s.regions_attrs["count"]), len(s.regions["region"]))
        self.assertEqual(int(round(s.regions["placed"].sum())), len(s.undergrowth))
        # Parameters stored as text come back as numbers and booleans.
        self.assertIsInstance(s.parameters["max_passes"], int)
        self.assertIsInstance(s.parameters["undergrowth_shades"], bool)


class TestFormatChecks(unittest.TestCase):
    def copy_with(self, source, name, **attrs):
        target = path(name)
        shutil.copyfile(path(source), target)
        with h5py.File(target, "r+") as f:
            for k, v in attrs.items():
                if v is None:
                    del f.attrs[k]
                else:
                    f.attrs[k] = v
        return target

    def truncate_features(self, target, keep):
        # The feature columns of a database cut to the first `keep` factors (as a database
        # written before the others existed would have them).
        with h5py.File(target, "r+") as f:
            if "features/weights" in f:
                del f["features/weights"]
            for name in ("features/names", "features/units", "combinations/feature_mean", "combinations/feature_std",
                         "regions/centroid_normalised", "regions/centroid_raw"):
                old = f[name]
                data, dtype, attrs = old[()], old.dtype, dict(old.attrs)
                del f[name]
                new = f.create_dataset(name, data=data[..., :keep], dtype=dtype)
                for k, v in attrs.items():
                    new.attrs[k] = v

    def test_a_database_before_the_wind_column_is_still_read_by_eco(self):
        # Schema 4 had four feature columns and no /features/weights: made here from the
        # schema 5 database, eco must read it with the wind left out (weight 0) and find the
        # same regions, so the same scene comes out of it (docs/database.md, "Versions").
        target = self.copy_with("db.h5", "db-v4.h5", schema_version=np.int64(4))
        with h5py.File(target, "r") as f:
            last = f["features/names"][()][-1]
            self.assertEqual(last.decode() if isinstance(last, bytes) else last, "wind")
        self.truncate_features(target, 4)
        listing = run_eco("inspect-v4", "inspect", "db-v4.h5")
        self.assertIn("schema 4", listing)
        strip = lambda text: [re.sub(r", wind [-0-9.e+]+ m/s", "", line) for line in text.splitlines()
                              if "centroid" in line]
        self.assertTrue(strip(LOG["inspect"]))
        self.assertEqual(strip(listing), strip(LOG["inspect"]))
        run_eco("synth-v4", "synth", "--terrain", "terrain.h5", "--canopy", "canopy.h5", "--database", "db-v4.h5",
                "--abiotics", "abiotics.h5", "--out", "scene-v4.h5", "--csv", "scene-v4.csv")
        with open(path("scene.csv")) as a, open(path("scene-v4.csv")) as b:
            self.assertEqual(a.read(), b.read())

    def test_a_database_without_a_required_factor_is_refused_by_eco_naming_it(self):
        # A required factor added after a database was written is not guessed (docs/database.md
        # "Versions"): eco refuses the file, naming the factor it lacks, whatever its version.
        target = self.copy_with("db.h5", "db-three.h5")
        self.truncate_features(target, 3)
        r = subprocess.run([ECO, "inspect", "db-three.h5"], cwd=D, capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        for part in ("db-three.h5", "/features/names", "no feature 'slope'", "before the factor slope existed",
                     "re-run eco analyse"):
            self.assertIn(part, r.stderr)
        # By name, not by version: a version 5 file without the (optional) wind is read.
        target = self.copy_with("db.h5", "db-v5-no-wind.h5")
        self.truncate_features(target, 4)
        self.assertIn("schema 5", run_eco("inspect-v5-no-wind", "inspect", "db-v5-no-wind.h5"))

    def test_a_map_added_later_is_read_by_name_and_eco_reads_the_maps_it_knows(self):
        # A factor added to eco is one more grid dataset of the abiotics file, in the same
        # schema version (docs/factors.md): read_abiotics reads it by its name with no change
        # here, and eco reads such a file (written by a later eco) for the maps it knows.
        target = self.copy_with("abiotics.h5", "abiotics-more.h5")
        with h5py.File(target, "r+") as f:
            for name, source in (("soil_depth", "slope"), ("humidity", "moisture")):
                f.create_dataset(name, data=f[source][()] + 1)
                for k in ("cell_size_m", "origin_x_m", "origin_y_m"):
                    f[name].attrs[k] = f[source].attrs[k]
                f[name].attrs["units"] = "test units"
        a = eco.read_abiotics(target)
        ref = eco.read_abiotics(path("abiotics.h5"))
        self.assertEqual(set(a.grids), set(ref.grids) | {"soil_depth", "humidity"})
        np.testing.assert_array_equal(a.soil_depth.values, ref.slope.values + 1)
        self.assertIsNone(a.soil_depth.months)
        np.testing.assert_array_equal(a.humidity.months, np.arange(1, 13))
        np.testing.assert_array_equal(a.humidity.values, ref.moisture.values + 1)
        self.assertEqual(a.humidity.units, "test units")
        run_eco("synth-more", "synth", "--terrain", "terrain.h5", "--canopy", "canopy.h5", "--database", "db.h5",
                "--abiotics", "abiotics-more.h5", "--out", "scene-more.h5", "--csv", "scene-more.csv")
        with open(path("scene.csv")) as x, open(path("scene-more.csv")) as y:
            self.assertEqual(x.read(), y.read())
        # A file without one of the maps eco knows is refused naming it.
        target = self.copy_with("abiotics.h5", "abiotics-less.h5")
        with h5py.File(target, "r+") as f:
            del f["wind"]
        r = subprocess.run([ECO, "synth", "--terrain", "terrain.h5", "--canopy", "canopy.h5", "--database", "db.h5",
                            "--abiotics", "abiotics-less.h5", "--out", "scene-less.h5"], cwd=D, capture_output=True,
                           text=True, timeout=120)
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        for part in ("abiotics-less.h5", "dataset /wind is missing", "written before the wind map existed"):
            self.assertIn(part, r.stderr)

    def test_every_output_opens_by_its_format(self):
        kinds = {"terrain.h5": eco.Terrain, "chm.h5": eco.Chm, "abiotics.h5": eco.Abiotics, "canopy.h5": eco.Canopy,
                 "sim.h5": eco.Simulation, "db.h5": eco.Database, "scene.h5": eco.Scene}
        for name, kind in kinds.items():
            obj = eco.open(path(name))
            self.assertIsInstance(obj, kind, name)
            self.assertIn(obj.format, eco.FORMATS)
            self.assertTrue(obj.code_version, name)

    def test_wrong_kind_is_refused_naming_file_found_and_expected(self):
        with self.assertRaises(eco.EcoFormatError) as e:
            eco.read_scene(path("terrain.h5"))
        msg = str(e.exception)
        for part in (path("terrain.h5"), "'eco-terrain'", "'eco-scene'"):
            self.assertIn(part, msg)

    def test_unknown_schema_version_is_refused(self):
        target = self.copy_with("scene.h5", "scene-v99.h5", schema_version=np.int64(99))
        with self.assertRaises(eco.EcoFormatError) as e:
            eco.read_scene(target)
        self.assertRegex(str(e.exception), r"scene-v99\.h5: format 'eco-scene' schema_version 99 found, .*reads version 1")
        with self.assertRaises(eco.EcoFormatError):
            eco.open(target)
        target = self.copy_with("db.h5", "db-v1.h5", schema_version=np.int64(1))
        with self.assertRaisesRegex(eco.EcoFormatError, r"schema_version 1 found, .*reads version 2, 3, 4, 5"):
            eco.read_database(target)

    def test_unknown_or_missing_format_is_refused(self):
        target = self.copy_with("sim.h5", "odd.h5", format="eco-something-else")
        with self.assertRaisesRegex(eco.EcoFormatError, r"odd\.h5: unknown format 'eco-something-else'"):
            eco.open(target)
        target = self.copy_with("abiotics.h5", "unmarked.h5", format=None)
        with self.assertRaisesRegex(eco.EcoFormatError, r"unmarked\.h5: .*'format' is missing"):
            eco.read_abiotics(target)
        with self.assertRaisesRegex(eco.EcoFormatError, r"'format' is missing"):
            eco.open(target)
        target = self.copy_with("sim.h5", "no-version.h5", schema_version=None)
        with self.assertRaisesRegex(eco.EcoFormatError, r"'schema_version' is missing"):
            eco.read_simulation(target)
        with open(path("not-hdf5.h5"), "w") as f:
            f.write("plain text\n")
        with self.assertRaisesRegex(eco.EcoFormatError, r"not-hdf5\.h5: cannot open as HDF5"):
            eco.open(path("not-hdf5.h5"))

    def test_empty_table_and_variable_length_names_are_read(self):
        # An empty plant group, and names stored as variable-length strings (files written
        # before names became fixed-length, docs/hdf5.md).
        target = path("canopy-edge.h5")
        shutil.copyfile(path("canopy.h5"), target)
        with h5py.File(target, "r+") as f:
            g = f["canopy"]
            names = [n.decode() for n in g["species_names"][()]]
            del g["species_names"]
            g.create_dataset("species_names", data=names, dtype=h5py.string_dtype())
            for k in ("species_id", "x", "y", "ground_z", "height", "crown_radius"):
                dtype = g[k].dtype
                del g[k]
                g.create_dataset(k, shape=(0,), dtype=dtype)
        c = eco.read_canopy(target)
        self.assertEqual(len(c.trees), 0)
        self.assertEqual(c.trees.counts(), {})
        self.assertEqual(c.trees.species_names, names)

    def test_terrain_written_before_files_were_marked_is_read(self):
        # eco's own readers take any file with /terrain/elevation (docs/hdf5.md).
        target = self.copy_with("terrain.h5", "old-terrain.h5", format=None, schema_version=None)
        t = eco.open(target)
        self.assertEqual((t.format, t.schema_version), ("eco-terrain", 0))
        np.testing.assert_allclose(t.elevation.values, ASC[1][::-1], rtol=1e-6)


class TestPandas(unittest.TestCase):
    def setUp(self):
        try:
            import pandas  # noqa: F401
        except ImportError:
            self.skipTest("pandas is not installed (optional: python3-pandas)")

    def test_frames(self):
        sim = eco.read_simulation(path("sim.h5"))
        df = sim.final.to_pandas()
        self.assertEqual(len(df), len(sim.final))
        self.assertEqual(df.attrs["units"]["height"], "m")
        census = sim.census.to_pandas()
        self.assertEqual(len(census), len(sim.census.years) * len(sim.census.species_names))
        final = census[census["year"] == YEARS].set_index("species")["count"]
        for name, n in sim.final.counts().items():
            self.assertEqual(final[name], n)
        sun = eco.read_abiotics(path("abiotics.h5")).sun.to_pandas()
        self.assertEqual(len(sun), 12 * NX * NY)
        db = eco.read_database(path("db.h5"))
        self.assertEqual(len(db.regions_to_pandas()), db.n_regions)


def load_blender_recipe():
    """tools/blender_import_eco.py as a module (its readers need only numpy; bpy is imported
    inside build() alone)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("blender_import_eco", os.path.join(ROOT, "tools", "blender_import_eco.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class TestExportFor3D(unittest.TestCase):
    """eco instance's files for 3D packages (docs/export.md) read back with the Blender
    recipe's own readers, against the scene read through the package."""

    @classmethod
    def setUpClass(cls):
        run_eco("instance", "instance", "scene.h5", "--prototypes", "3", "--curve-max", "3", "--seed", "7", "--out", "inst")
        cls.recipe = load_blender_recipe()
        cls.scene = eco.read_scene(path("scene.h5"))

    def test_ply_holds_every_plant_with_its_csv_row(self):
        v, comments = self.recipe.read_ply(path("inst/instances.ply"))
        rows = self.recipe.read_csv(path("inst/instances.csv"))
        plants = self.scene.plants()  # canopy first, as the export
        self.assertEqual(len(v), len(plants))
        self.assertEqual(len(rows), len(plants))
        np.testing.assert_array_equal(v["id"], np.arange(len(v)))
        np.testing.assert_array_equal(v["layer"], (plants["layer"] == "canopy").astype(np.uint8))
        np.testing.assert_array_equal(v["species"], plants["species_id"])
        for field, column in (("x", "x"), ("y", "y"), ("z", "ground_z"), ("height", "height"),
                              ("crown_radius", "crown_radius")):
            np.testing.assert_allclose(v[field], plants[column], rtol=1e-6, atol=1e-4, err_msg=field)
        # The same rows as the CSV (floats to float32 precision).
        self.assertEqual([int(r["id"]) for r in rows], list(range(len(rows))))
        np.testing.assert_array_equal(v["prototype"], [int(r["prototype"]) for r in rows])
        # The CSV has 6 significant digits of the rotation (a half unit: 5e-6 relative), 8 of the scale.
        np.testing.assert_allclose(v["rotation_deg"], [float(r["rotation_deg"]) for r in rows], rtol=6e-6, atol=1e-6)
        np.testing.assert_allclose(v["scale"], [float(r["scale"]) for r in rows], rtol=1e-6)
        self.assertEqual([r["species"] for r in rows], list(plants["species"]))
        self.assertTrue(np.all((v["rotation_deg"] >= 0) & (v["rotation_deg"] < 360)))
        # The species' names in the header's comments; one colour per species.
        names = self.scene.canopy.species_names
        for sid in np.unique(v["species"]):
            self.assertIn(f"species {sid} {names[sid]}", comments)
            rgb = np.stack([v["red"], v["green"], v["blue"]], axis=1)[v["species"] == sid]
            self.assertEqual(len(np.unique(rgb, axis=0)), 1)

    def test_prototype_height_times_scale_is_the_plant_height(self):
        v, _ = self.recipe.read_ply(path("inst/instances.ply"))
        protos = self.recipe.read_csv(path("inst/prototypes.csv"))
        self.assertEqual([int(p["prototype"]) for p in protos], list(range(len(protos))))
        height = np.array([float(p["height_m"]) for p in protos])
        species = np.array([int(p["species_id"]) for p in protos])
        np.testing.assert_allclose(height[v["prototype"]] * v["scale"], v["height"], rtol=1e-5)
        np.testing.assert_array_equal(species[v["prototype"]], v["species"])
        self.assertLessEqual(np.bincount(species).max(), 3)  # --prototypes 3

    def test_exr_maps_are_the_scene_grids_north_up_with_their_geometry(self):
        for name, grid, units in (("grass", self.scene.grass, "1"), ("litter", self.scene.litter, "1"),
                                  ("terrain", self.scene.terrain, "m")):
            with self.subTest(name=name):
                image, attrs = self.recipe.read_exr(path(f"inst/{name}.exr"))
                self.assertEqual(image.shape, grid.values.shape)
                np.testing.assert_array_equal(image, grid.north_up().astype(np.float32))
                self.assertAlmostEqual(float(attrs["eco:cell_size_m"]), grid.cell_size_m)
                self.assertAlmostEqual(float(attrs["eco:origin_x_m"]), grid.origin_x_m)
                self.assertAlmostEqual(float(attrs["eco:origin_y_m"]), grid.origin_y_m)
                self.assertEqual(attrs["eco:units"], units)
                self.assertEqual(attrs["channels"][0][0], "Y")


class TestDocsExamples(unittest.TestCase):
    """The ```python blocks of docs/python.md run against this scene's files, placed where
    `eco run configs/demo.toml` writes them (out/demo/)."""

    def test_docs_examples_run(self):
        with open(os.path.join(ROOT, "docs", "python.md")) as f:
            blocks = re.findall(r"```python\n(.*?)```", f.read(), re.S)
        self.assertGreaterEqual(len(blocks), 4)
        demo = path("docs/out/demo")
        os.makedirs(demo, exist_ok=True)
        for source, name in (("scene.h5", "scene.h5"), ("db.h5", "biome-db.h5"), ("sim.h5", "simulation.h5"),
                             ("abiotics.h5", "abiotics.h5")):
            if not os.path.exists(os.path.join(demo, name)):
                os.symlink(path(source), os.path.join(demo, name))
        cwd = os.getcwd()
        os.chdir(path("docs"))
        try:
            for i, block in enumerate(blocks):
                with self.subTest(block=i):
                    with contextlib.redirect_stdout(io.StringIO()):
                        exec(compile(block, f"docs/python.md block {i + 1}", "exec"), {"__name__": "docs_example"})
        finally:
            os.chdir(cwd)


if __name__ == "__main__":
    unittest.main()

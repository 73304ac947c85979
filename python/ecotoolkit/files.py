"""Readers for every HDF5 file eco writes (docs/hdf5.md "The files")."""

import h5py
import numpy as np

from ._h5 import (EcoFormatError, attrs_of, decode, is_dimension_scale, open_checked, read_strings, sniff_format,
                  unit_of)
from .grid import read_grid
from .plants import read_plants


class EcoFile:
    """What every reader returns: ``path``, ``format``, ``schema_version`` (0 for a terrain
    or CHM file written before eco marked its files), ``code_version`` and ``attrs`` (all
    root attributes, strings decoded), plus ``provenance`` (the attributes of
    ``/provenance``: measured values such as wall times, empty when absent)."""

    def __init__(self, path, fmt, version, f):
        self.path = str(path)
        self.format = fmt
        self.schema_version = version
        self.attrs = attrs_of(f)
        self.code_version = self.attrs.get("code_version", "")
        self.provenance = attrs_of(f["provenance"]) if "provenance" in f else {}

    def __repr__(self):
        return f"{type(self).__name__}({self.path!r}, format {self.format!r} v{self.schema_version})"


def _columns(f, group, path, documented_units):
    """The 1-D datasets of ``group`` as a dict of arrays and a dict of units."""
    if group not in f:
        raise EcoFormatError(f"{path}: group {group} is missing")
    out, units = {}, {}
    for name, ds in f[group].items():
        if not hasattr(ds, "shape") or is_dimension_scale(ds):
            continue
        out[name] = read_strings(ds) if ds.dtype.kind in ("S", "O") else ds[()]
        units[name] = unit_of(ds, documented_units.get(name, ""))
    return out, units


# ------------------------------------------------------------------------------- terrain, CHM

class Terrain(EcoFile):
    """``elevation``: Grid (metres), from ``/terrain/elevation``."""


def read_terrain(path):
    """A terrain file (``eco terrain generate`` / ``eco terrain convert``, format eco-terrain)."""
    f, fmt, version = open_checked(path, "eco-terrain", allow_unmarked_with="/terrain/elevation")
    with f:
        t = Terrain(path, fmt, version, f)
        t.elevation = read_grid(f, "/terrain/elevation", path, monthly=False)
    return t


class Chm(EcoFile):
    """``height`` (Grid, metres above ground), ``sketch`` (Grid, density level 0 empty,
    1 sparse, 2 dense; None when absent), ``trees`` (dict of arrays x_m, y_m, height_m,
    crown_radius_m: the trees the CHM was rasterised from, metres), ``generator`` (the
    attributes of ``/chm``: the generator's parameters)."""


def read_chm(path):
    """A canopy height model (``eco chm generate``, format eco-chm)."""
    f, fmt, version = open_checked(path, "eco-chm", allow_unmarked_with="/chm/height")
    with f:
        c = Chm(path, fmt, version, f)
        c.height = read_grid(f, "/chm/height", path, monthly=False)
        c.sketch = read_grid(f, "/chm/sketch", path, monthly=False) if "/chm/sketch" in f else None
        c.trees, c.tree_units = (_columns(f, "/chm/trees", path, {k: "m" for k in ("x_m", "y_m", "height_m", "crown_radius_m")})
                                 if "/chm/trees" in f else ({}, {}))
        c.generator = attrs_of(f["/chm"])
    return c


# ------------------------------------------------------------------------------- abiotics

class Abiotics(EcoFile):
    """One Grid per map of the file, by its dataset's name: ``elevation`` (m), ``slope``
    (degrees), ``wind`` (m/s, schema 2; None in a schema 1 file): 2-D Grids; ``sun``
    (hours/day), ``moisture`` (mm/month), ``temperature`` (degC): monthly Grids
    ``[12][y][x]`` with ``months`` 1..12. ``grids``: all by name. The maps are the grid
    datasets the file holds (a 3-D one is monthly), so a map added to eco later is read
    with no change here. Climate and model parameters are in ``attrs`` (e.g.
    ``attrs["climate_rainfall_mm"]``, 12 values)."""

    wind = None


#: The maps every eco-abiotics file has (the paper's four factors and the terrain).
_ABIOTICS_REQUIRED = ("elevation", "slope", "sun", "moisture", "temperature")


def read_abiotics(path):
    """Abiotic maps (``eco abiotics``, format eco-abiotics): every grid dataset at the
    file's root (one with a cell size, not a coordinate scale), by name."""
    f, fmt, version = open_checked(path, "eco-abiotics")
    with f:
        a = Abiotics(path, fmt, version, f)
        a.grids = {}
        for name in _ABIOTICS_REQUIRED:
            if name not in f:
                raise EcoFormatError(f"{path}: dataset /{name} is missing")
        for name, obj in f.items():
            if not isinstance(obj, h5py.Dataset) or is_dimension_scale(obj) or "cell_size_m" not in obj.attrs:
                continue
            grid = read_grid(f, "/" + name, path)
            if grid.values.ndim == 3 and grid.values.shape[0] != 12:
                raise EcoFormatError(f"{path}: /{name}: {grid.values.shape[0]} planes, expected 12 (one per month)")
            a.grids[name] = grid
            if name not in vars(a):
                setattr(a, name, grid)
    return a


# ------------------------------------------------------------------------------- canopy

_ITERATION_UNITS = {"iteration": "", "trees": "trees", "removed": "trees", "added": "trees",
                    "coverage": "fraction of the CHM footprint", "rmse_m": "m", "seconds": "s"}
_TARGET_UNITS = {"requested": "fraction of the forested area", "achieved": "fraction of the forested area",
                 "reachable": "fraction of the forested area", "weight": "", "alpha": "", "feasible": "",
                 "iterations": ""}


class Canopy(EcoFile):
    """``trees``: Plants (``/canopy``); ``species_map`` (Grid, species id, -1 none; names in
    ``trees.species_names``), ``chm`` (Grid, m), ``terrain`` (Grid, m); ``iterations``
    (dict of arrays, one row per placement iteration; ``iteration_units``) and ``targets``
    (dict of arrays of the species-share targets, empty without targets; ``target_mask``
    Grid or None)."""


def read_canopy(path):
    """Placed canopy trees (``eco canopy``, format eco-canopy, schema 1 or 2)."""
    f, fmt, version = open_checked(path, "eco-canopy")
    with f:
        c = Canopy(path, fmt, version, f)
        c.trees = read_plants(f, "/canopy", path)
        c.species_map = read_grid(f, "/species_map", path, monthly=False)
        c.chm = read_grid(f, "/chm/height", path, monthly=False)
        c.terrain = read_grid(f, "/terrain/elevation", path, monthly=False)
        c.iterations, c.iteration_units = _columns(f, "/iterations", path, _ITERATION_UNITS)
        c.targets, c.target_units, c.target_mask = {}, {}, None
        if "/targets" in f:
            c.targets, c.target_units = _columns(f, "/targets", path, _TARGET_UNITS)
            c.targets.pop("mask", None)
            if "/targets/mask" in f:
                c.target_mask = read_grid(f, "/targets/mask", path, monthly=False)
    return c


# ------------------------------------------------------------------------------- simulation

#: Units of the census (``/timeseries``) as core/sim_file.cpp documents them.
CENSUS_UNITS = {"year": "years", "count": "plants", "mean_height": "m", "mean_vigour": "dimensionless",
                "crown_area": "m^2"}


class Census:
    """The yearly census of a simulation (``/timeseries``): ``years`` (int, complete years
    simulated, 0 = initial state), ``species_names``, and per quantity an array
    ``[year][species]``: ``count`` (plants), ``mean_height`` (m), ``mean_vigour``
    (dimensionless), ``crown_area`` (m^2, sum of pi r^2). ``units`` maps each to its unit."""

    QUANTITIES = ("count", "mean_height", "mean_vigour", "crown_area")

    def __init__(self, years, species_names, values, units):
        self.years = years
        self.species_names = species_names
        self.values = values
        self.units = units
        for k, v in values.items():
            setattr(self, k, v)

    def of_species(self, species):
        """Dict quantity -> array over ``years`` for one species (name or id)."""
        s = self.species_names.index(species) if isinstance(species, str) else int(species)
        return {k: v[:, s] for k, v in self.values.items()}

    def to_pandas(self):
        """A long pandas DataFrame: year, species and one column per quantity. Needs pandas."""
        import pandas as pd
        ny, ns = len(self.years), len(self.species_names)
        df = pd.DataFrame({"year": np.repeat(self.years, ns),
                           "species": pd.Categorical(np.tile(self.species_names, ny), categories=self.species_names)})
        for k, v in self.values.items():
            df[k] = v.reshape(-1)
        df.attrs["units"] = dict(self.units)
        return df

    def __repr__(self):
        return f"Census({len(self.years)} years x {len(self.species_names)} species)"


class Disturbance:
    """A disturbance event of a simulation (``/disturbance``, docs/disturbance.md): ``year``
    (simulated year, 0 = the first), ``month`` (0 = January), ``kind`` ("fire" or "storm"),
    ``area_m2``, ``x``, ``y`` (ignition or the area's centre, m), ``killed`` (int array per
    species), ``killed_total``; and its mask: ``mask`` (bool array [row][column], row 0 the
    SOUTHERN row, as eco's grids; None for files written before the masks), ``mask_extent``
    (x0, y0, x1, y1 of the mask grid, m) and ``mask_cell_m``. A fire's mask is its burnt
    cells, a storm's the cells in which at least one plant was thrown."""

    def __init__(self, **kw):
        self.__dict__.update(kw)

    def mask_contains(self, x, y):
        """True where world points (x, y) (scalars or arrays, m) fall in a struck cell."""
        if self.mask is None:
            raise ValueError("this event has no mask (file written before the masks)")
        x0, y0 = self.mask_extent[0], self.mask_extent[1]
        cx = np.floor((np.asarray(x, dtype=float) - x0) / self.mask_cell_m).astype(np.int64)
        cy = np.floor((np.asarray(y, dtype=float) - y0) / self.mask_cell_m).astype(np.int64)
        h, w = self.mask.shape
        inside = (cx >= 0) & (cy >= 0) & (cx < w) & (cy < h)
        out = np.zeros(np.broadcast(cx, cy).shape, dtype=bool)
        out[inside] = self.mask[cy[inside], cx[inside]]
        return out

    def __repr__(self):
        return f"Disturbance({self.kind}, year {self.year}, {self.area_m2:.0f} m2, killed {self.killed_total})"


def _read_disturbances(f):
    if "disturbance" not in f:
        return []
    d = f["disturbance"]
    year = d["year"][()]
    n = len(year)
    if n == 0:  # disturbance configured, no event in the run
        return []
    kind = read_strings(d["kind"])
    killed = d["killed"][()].reshape(n, -1)
    out = []
    has_mask = "mask_offset" in d
    if has_mask:
        offset, cells = d["mask_offset"][()], d["mask_cells"][()]
        mw, mh = d["mask_width"][()], d["mask_height"][()]
        mx, my, mc = d["mask_origin_x"][()], d["mask_origin_y"][()], d["mask_cell_size"][()]
    for e in range(n):
        mask = extent = cell = None
        if has_mask and mw[e] > 0 and mh[e] > 0:
            flat = np.zeros(int(mw[e]) * int(mh[e]), dtype=bool)
            flat[cells[offset[e]:offset[e + 1]]] = True
            mask = flat.reshape(int(mh[e]), int(mw[e]))
            cell = float(mc[e])
            extent = (float(mx[e]), float(my[e]), float(mx[e]) + cell * int(mw[e]), float(my[e]) + cell * int(mh[e]))
        out.append(Disturbance(year=int(year[e]), month=int(d["month"][e]), kind=kind[e], area_m2=float(d["area"][e]),
                               x=float(d["x"][e]), y=float(d["y"][e]), killed=killed[e],
                               killed_total=int(killed[e].sum()), mask=mask, mask_extent=extent, mask_cell_m=cell))
    return out


class Simulation(EcoFile):
    """``snapshots``: dict year -> Plants (undergrowth with its state), ``years``: the
    snapshot years ascending, ``final``: the last snapshot; ``census``: Census;
    ``canopy``: Plants (the canopy trees near the simulated area); ``window_m``:
    (x0, y0, x1, y1) of the simulated area, world metres; ``species_names``;
    ``disturbances``: list of Disturbance (empty when the run had none configured)."""


def read_simulation(path):
    """An undergrowth simulation (``eco simulate``, format eco-simulation)."""
    f, fmt, version = open_checked(path, "eco-simulation")
    with f:
        s = Simulation(path, fmt, version, f)
        s.species_names = read_strings(f["species_names"]) if "species_names" in f else None
        s.window_m = tuple(float(s.attrs[k]) for k in ("x0", "y0", "x1", "y1"))
        if "snapshots" not in f:
            raise EcoFormatError(f"{path}: group /snapshots is missing")
        s.snapshots = {}
        for name, g in f["snapshots"].items():
            year = int(decode(g.attrs["year"])) if "year" in g.attrs else int(name.split("_")[-1])
            s.snapshots[year] = read_plants(f, f"/snapshots/{name}", path)
        s.years = sorted(s.snapshots)
        s.final = s.snapshots[s.years[-1]] if s.years else None
        s.canopy = read_plants(f, "/canopy", path) if "/canopy" in f else None
        s.census = None
        if "timeseries" in f:
            ts = f["timeseries"]
            values = {k: ts[k][()] for k in Census.QUANTITIES if k in ts}
            units = {k: unit_of(ts[k], CENSUS_UNITS[k]) for k in values}
            units["year"] = CENSUS_UNITS["year"]
            names = read_strings(ts["species_names"]) if "species_names" in ts else s.species_names
            s.census = Census(ts["year"][()].astype(np.int64), names, values, units)
        s.disturbances = _read_disturbances(f)
    return s


# ------------------------------------------------------------------------------- scene

_SCENE_REGION_UNITS = {"region": "", "combination": "bitmask", "cluster": "", "cells": "cells", "area_m2": "m^2",
                       "target_density_per_m2": "plants/m^2", "target_count": "plants", "placed": "plants",
                       "density_per_m2": "plants/m^2", "cluster_fields": "", "cluster_sigma_m": "m",
                       "cluster_parents_per_m2": "1/m^2", "cluster_pooled_amplitude": "",
                       "pooled_g_fit_rms": "", "pooled_g_context_only_rms": "", "deussen_species_order": "",
                       "deussen_halftone_cell_m": "m", "deussen_min_distance_m": "m", "deussen_dots": "dots",
                       "deussen_dropped": "dots", "deussen_clark_evans_before": "", "deussen_clark_evans_after": ""}


class Scene(EcoFile):
    """A synthesized scene: ``canopy`` and ``undergrowth`` (Plants), ``grass`` and
    ``litter`` (Grids, density 0..1), ``cluster_map`` (Grid, database region index, -1
    none), ``combination_map`` (Grid, sub-biome bitmask), ``terrain`` (Grid, m);
    ``regions`` (dict of arrays per database region used, ``region_units``),
    ``refinement`` (attributes of ``/refinement``) and ``parameters`` (the synthesis
    parameters from the root attributes, numbers parsed where the file stores them as text)."""

    def plants(self):
        """Canopy and undergrowth in one structured array with a ``layer`` field."""
        layers = [("canopy", self.canopy), ("undergrowth", self.undergrowth)]
        width = max(p.data.dtype["species"].itemsize for _, p in layers) // 4  # numpy 'U': 4 bytes a character
        dtype = [("layer", "U11")] + [(n, f"U{width}" if n == "species" else self.canopy.data.dtype[n])
                                      for n in self.canopy.fields]
        out = np.empty(len(self.canopy) + len(self.undergrowth), dtype=dtype)
        i = 0
        for layer, p in layers:
            out["layer"][i:i + len(p)] = layer
            for n in self.canopy.fields:
                out[n][i:i + len(p)] = p.data[n]
            i += len(p)
        return out


def _parse_number(v):
    if isinstance(v, str):
        if v in ("true", "false"):
            return v == "true"
        try:
            return int(v)
        except ValueError:
            try:
                return float(v)
            except ValueError:
                return v
    return v


_SCENE_NON_PARAMETERS = {"format", "schema_version", "code_version", "biome_toml", "biome_name", "units",
                         "database_path", "database_code_version", "terrain_source", "canopy_source",
                         "abiotics_source", "created_utc", "database_created_utc"}


def read_scene(path):
    """A synthesized scene (``eco synth``, format eco-scene)."""
    f, fmt, version = open_checked(path, "eco-scene")
    with f:
        s = Scene(path, fmt, version, f)
        s.canopy = read_plants(f, "/canopy", path)
        s.undergrowth = read_plants(f, "/undergrowth", path)
        s.grass = read_grid(f, "/forest_floor/grass", path, monthly=False)
        s.litter = read_grid(f, "/forest_floor/litter", path, monthly=False)
        s.cluster_map = read_grid(f, "/cluster_map", path, monthly=False)
        s.combination_map = read_grid(f, "/combination_map", path, monthly=False)
        s.terrain = read_grid(f, "/terrain/elevation", path, monthly=False)
        s.regions, s.region_units = _columns(f, "/regions", path, _SCENE_REGION_UNITS)
        s.regions_attrs = attrs_of(f["/regions"])
        s.refinement = attrs_of(f["/refinement"]) if "/refinement" in f else {}
        if "/refinement/objective_per_sweep" in f:
            s.refinement["objective_per_sweep"] = f["/refinement/objective_per_sweep"][()]
        s.parameters = {k: _parse_number(v) for k, v in s.attrs.items() if k not in _SCENE_NON_PARAMETERS}
    return s


# ------------------------------------------------------------------------------- dispatch

def open(path):  # noqa: A001 - the natural name for "open any eco file"
    """Read any eco HDF5 file by its root ``format`` attribute: returns a Terrain, Chm,
    Abiotics, Canopy, Simulation, Database or Scene. EcoFormatError for anything else."""
    from .database import read_database
    readers = {"eco-terrain": read_terrain, "eco-chm": read_chm, "eco-abiotics": read_abiotics,
               "eco-canopy": read_canopy, "eco-simulation": read_simulation, "eco-biome-db": read_database,
               "eco-scene": read_scene}
    fmt = sniff_format(path)
    if fmt is None:
        # Terrain and CHM files from before eco marked them: eco's readers take them too.
        import h5py
        with h5py.File(path, "r") as f:
            if "/terrain/elevation" in f:
                return read_terrain(path)
            if "/chm/height" in f:
                return read_chm(path)
        raise EcoFormatError(f"{path}: not an eco file: root attribute 'format' is missing "
                             f"(expected one of {', '.join(sorted(readers))})")
    if fmt not in readers:
        raise EcoFormatError(f"{path}: unknown format '{fmt}' (this ecotoolkit reads {', '.join(sorted(readers))})")
    return readers[fmt](path)

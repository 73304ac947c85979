"""The biome database (``eco analyse``, format eco-biome-db): docs/database.md."""

import numpy as np

from ._h5 import EcoFormatError, attrs_of, is_dimension_scale, open_checked, read_strings, unit_of
from .files import EcoFile, _parse_number

#: Units of the database's datasets as docs/database.md gives them (the files of schema
#: 2..4 carry none); a dataset's own ``units`` attribute wins when present.
DB_UNITS = {
    # /bins
    "pcf_edges_m": "m", "pcf_annulus_area_m2": "m^2", "separation_edges_m": "m", "context_edges_m": "m",
    # /combinations
    "mask": "bitmask", "k": "", "first_region": "", "area_m2": "m^2", "cell_count": "cells",
    "feature_mean": "feature units", "feature_std": "feature units", "silhouette": "",
    # /regions
    "combination": "bitmask", "cluster": "", "centroid_normalised": "z", "centroid_raw": "feature units",
    "undergrowth_count": "plants", "canopy_count": "trees", "density_per_m2": "plants/m^2",
    "input_area_m2": "m^2", "species_count": "plants", "species_proportion": "", "canopy_species_count": "trees",
    # /regions/region_RRRR
    "height_edges_m": "m", "height_counts": "plants", "height_overflow": "plants",
    "crown_radius_edges_m": "m", "crown_radius_counts": "plants", "crown_radius_overflow": "plants",
    "context_area_m2": "m^2", "context_species_count": "plants", "height_covered_counts": "plants",
    "height_covered_overflow": "plants", "context_cell_pairs": "cell pairs",
    # /regions/region_RRRR/pairs
    "source": "category", "target": "category", "pair_count": "pairs", "translate_weighted": "",
    "normalisation_per_m2": "1/m^2", "g": "", "separation_count": "pairs", "separation_underflow": "pairs",
    "separation_sources": "plants",
}


def _datasets(group):
    out, units = {}, {}
    for name, ds in group.items():
        if hasattr(ds, "shape") and not is_dimension_scale(ds):
            out[name] = read_strings(ds) if ds.dtype.kind in ("S", "O") else ds[()]
            units[name] = unit_of(ds, DB_UNITS.get(name, ""))
    return out, units


class Region:
    """One database region (a sub-biome combination and a cluster): ``index``,
    ``combination`` (bitmask), ``cluster``, ``attrs``; ``histograms``: dict of arrays
    (``height_edges_m`` [S][HB+1], ``height_counts`` [S][HB], ``crown_radius_*``, and in
    schema 3+ the canopy-context statistics); ``pairs``: dict of arrays, one row per stored
    ordered pair of categories (``source``, ``target`` category indices, ``g`` [P][NB],
    ``pair_count``, ``translate_weighted``, ``normalisation_per_m2``, ``separation_*``),
    plus ``source_name`` / ``target_name``; ``units`` for both."""

    def __init__(self, index, attrs, histograms, pairs, units):
        self.index = index
        self.attrs = attrs
        self.combination = attrs.get("combination")
        self.cluster = attrs.get("cluster")
        self.histograms = histograms
        self.pairs = pairs
        self.units = units

    def __repr__(self):
        n = len(self.pairs.get("source", ()))
        return f"Region({self.index}: combination {self.combination}, cluster {self.cluster}, {n} pairs)"


class Database(EcoFile):
    """A biome database. ``species_names``; ``sub_biome_names`` (sub-biome b at index
    b - 1); ``categories``: structured array (``name``, ``layer`` 0 undergrowth / 1 canopy,
    ``species``), category c = layer * n_species + species; ``feature_names`` and
    ``feature_units``; ``parameters`` (the analysis parameters, numbers parsed);
    ``bins`` (dict: the ``/bins`` attributes and edge arrays) with ``pcf_r_m`` the centres of
    the distance bins; ``inputs`` (list of dicts, one per analysed input);
    ``combinations`` and ``regions`` (dicts of arrays, one row per combination / region;
    ``combination_units``, ``region_units``); ``region(i)``: a Region with histograms
    and pair statistics; ``pcf(region, source, target)``: g(r)."""

    @property
    def n_regions(self):
        return len(self._regions)

    def region(self, index):
        """Region ``index`` (0-based, as in ``/regions/region_RRRR``)."""
        if not 0 <= index < len(self._regions):
            raise IndexError(f"{self.path}: region {index} out of 0..{len(self._regions) - 1}")
        return self._regions[index]

    def category(self, c):
        """The index of a category given as an index or a name (``"Toyon"`` is the
        undergrowth category, ``"Toyon (canopy)"`` the canopy one)."""
        if isinstance(c, (int, np.integer)):
            return int(c)
        names = list(self.categories["name"])
        if c not in names:
            raise KeyError(f"{self.path}: no category {c!r} (categories: {', '.join(names)})")
        return names.index(c)

    def pcf(self, region, source, target, quantity="g"):
        """(r_m, values): the distance-bin centres (m) and ``quantity`` (``g``,
        ``pair_count`` or ``translate_weighted``) of the ordered pair source -> target
        (category names or indices) in ``region``. KeyError when the pair is not stored
        (docs/database.md: pairs whose source does not occur in the region)."""
        reg = self.region(region)
        s, t = self.category(source), self.category(target)
        rows = np.nonzero((reg.pairs["source"] == s) & (reg.pairs["target"] == t))[0]
        if len(rows) == 0:
            raise KeyError(f"{self.path}: region {region} stores no pair {self.categories['name'][s]} -> "
                           f"{self.categories['name'][t]}")
        return self.pcf_r_m, reg.pairs[quantity][rows[0]]

    def pcf_table(self, region):
        """All stored pairs of a region in one structured array: ``source``, ``target``
        (names), ``r_m`` and ``g`` (one row per pair and distance bin): ready for plotting
        or ``pandas.DataFrame``."""
        reg = self.region(region)
        nb = len(self.pcf_r_m)
        p = len(reg.pairs["source"])
        width = max(len(n) for n in self.categories["name"])
        out = np.empty(p * nb, dtype=[("source", f"U{width}"), ("target", f"U{width}"), ("r_m", "f8"),
                                      ("g", "f8"), ("pair_count", "f8")])
        out["source"] = np.repeat(self.categories["name"][reg.pairs["source"]], nb)
        out["target"] = np.repeat(self.categories["name"][reg.pairs["target"]], nb)
        out["r_m"] = np.tile(self.pcf_r_m, p)
        out["g"] = reg.pairs["g"].reshape(-1)
        out["pair_count"] = reg.pairs["pair_count"].reshape(-1)
        return out

    def regions_to_pandas(self):
        """The per-region table (1-D columns of ``/regions``; species proportions as one
        column per species) as a pandas DataFrame. Needs pandas."""
        import pandas as pd
        df = pd.DataFrame({k: v for k, v in self.regions.items() if np.ndim(v) == 1})
        for i, name in enumerate(self.species_names):
            df[f"proportion {name}"] = self.regions["species_proportion"][:, i]
        df.attrs["units"] = dict(self.region_units)
        return df


def read_database(path):
    """A biome database (format eco-biome-db, schema 2, 3 or 4)."""
    f, fmt, version = open_checked(path, "eco-biome-db")
    with f:
        db = Database(path, fmt, version, f)
        db.species_names = read_strings(f["species/names"])
        db.canopy_subbiome_mask = f["species/canopy_subbiome_mask"][()] if "species/canopy_subbiome_mask" in f else None
        db.sub_biome_names = read_strings(f["sub_biomes/names"])
        names = read_strings(f["categories/names"])
        width = max([1, *map(len, names)])
        db.categories = np.empty(len(names), dtype=[("name", f"U{width}"), ("layer", "i4"), ("species", "i4")])
        db.categories["name"] = names
        db.categories["layer"] = f["categories/layer"][()]
        db.categories["species"] = f["categories/species"][()]
        db.feature_names = read_strings(f["features/names"])
        db.feature_units = read_strings(f["features/units"])
        db.parameters = {n: _parse_number(v) for n, v in zip(read_strings(f["parameters/names"]),
                                                              read_strings(f["parameters/values"]))}
        db.bins = attrs_of(f["bins"])
        bins, db.bin_units = _datasets(f["bins"])
        db.bins.update(bins)
        edges = db.bins["pcf_edges_m"]
        db.pcf_r_m = 0.5 * (edges[:-1] + edges[1:])
        db.inputs = [attrs_of(g) for _, g in sorted(f["inputs"].items())] if "inputs" in f else []
        db.combinations, db.combination_units = _datasets(f["combinations"])
        db.regions, db.region_units = _datasets(f["regions"])
        db._regions = []
        groups = sorted(k for k in f["regions"].keys() if k.startswith("region_"))
        for i, name in enumerate(groups):
            if name != f"region_{i:04d}":
                raise EcoFormatError(f"{path}: /regions/{name} found where region_{i:04d} was expected")
            g = f["regions"][name]
            hist, units = _datasets(g)
            pairs, pair_units = ({}, {})
            if "pairs" in g:
                pairs, pair_units = _datasets(g["pairs"])
                pairs["source_name"] = db.categories["name"][pairs["source"]]
                pairs["target_name"] = db.categories["name"][pairs["target"]]
            units.update(pair_units)
            db._regions.append(Region(i, attrs_of(g), hist, pairs, units))
        count = db.regions.get("combination")
        if count is not None and len(count) != len(db._regions):
            raise EcoFormatError(f"{path}: /regions has {len(count)} rows but {len(db._regions)} region groups")
    return db

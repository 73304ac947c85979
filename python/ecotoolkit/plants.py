"""Plant tables: the plant groups of docs/hdf5.md "Plant lists" and core/plants.h."""

import numpy as np

from ._h5 import EcoFormatError, decode, read_strings, unit_of

#: Units of the plant columns as core/plants.h and core/sim_file.cpp write them (the files
#: carry only a group-level summary); a column's own ``units`` attribute wins when present.
PLANT_UNITS = {
    "id": "",
    "species_id": "",
    "species": "",
    "x": "m",
    "y": "m",
    "ground_z": "m",
    "height": "m",
    "crown_radius": "m",
    "age": "years",
    "growth_age": "years",
    "vigour": "dimensionless",
    "pool": "dimensionless",
    "sun_share": "hours/day",
    "water_share": "mm/month",
}

_FLOAT_COLUMNS = ("x", "y", "ground_z", "height", "crown_radius")
_STATE_COLUMNS = ("age", "growth_age", "vigour", "pool", "sun_share", "water_share")


class Plants:
    """One plant group as a numpy structured array, one row per plant.

    Fields: ``species_id`` (int32, index into ``species_names``), ``species`` (the name),
    ``x``, ``y`` (world metres, x east, y north), ``ground_z``, ``height``, ``crown_radius``
    (metres); a simulation snapshot adds ``id`` (int64) and ``age``, ``growth_age``,
    ``vigour``, ``pool``, ``sun_share``, ``water_share``. ``units`` maps each field to its
    unit, ``attrs`` holds the group's attributes. ``plants["height"]`` is a column.
    """

    def __init__(self, data, species_names, units, name="", attrs=None):
        self.data = data
        self.species_names = list(species_names)
        self.units = dict(units)
        self.name = name
        self.attrs = dict(attrs or {})

    def __len__(self):
        return len(self.data)

    def __getitem__(self, key):
        return self.data[key]

    @property
    def fields(self):
        return self.data.dtype.names

    def of_species(self, species):
        """The plants of one species (name or id) as a Plants."""
        sid = self.species_names.index(species) if isinstance(species, str) else int(species)
        return Plants(self.data[self.data["species_id"] == sid], self.species_names, self.units,
                      f"{self.name}[{self.species_names[sid]}]", self.attrs)

    def counts(self):
        """Plants per species name (species without plants left out)."""
        ids, n = np.unique(self.data["species_id"], return_counts=True)
        return {self.species_names[i]: int(c) for i, c in zip(ids, n)}

    def to_pandas(self):
        """A pandas DataFrame of the table (``species`` as a categorical in biome order);
        ``df.attrs["units"]`` holds the units. Needs pandas."""
        import pandas as pd
        df = pd.DataFrame({name: self.data[name] for name in self.fields})
        df["species"] = pd.Categorical(df["species"], categories=self.species_names)
        df.attrs["units"] = dict(self.units)
        return df

    def __repr__(self):
        return f"Plants({self.name!r}: {len(self)} plants, fields {', '.join(self.fields)})"


def read_plants(f, group, path):
    """The plant group ``group`` of an open h5py file as Plants."""
    if group not in f:
        raise EcoFormatError(f"{path}: plant group {group} is missing")
    g = f[group]
    for name in ("species_id", "species_names") + _FLOAT_COLUMNS:
        if name not in g:
            raise EcoFormatError(f"{path}: {group}/{name} is missing")
    names = read_strings(g["species_names"])
    species_id = g["species_id"][()].astype(np.int32)
    n = len(species_id)
    if n and (species_id.min() < 0 or species_id.max() >= len(names)):
        raise EcoFormatError(f"{path}: {group}/species_id out of 0..{len(names) - 1}")
    columns = [("species_id", species_id)]
    has_id = "id" in g
    if has_id:
        ids = g["id"][()]
        columns.insert(0, ("id", ids.astype(np.int64)))
    columns.append(("species", np.array([names[i] for i in species_id], dtype=f"U{max([1, *map(len, names)])}")))
    columns += [(c, g[c][()].astype(np.float64)) for c in _FLOAT_COLUMNS]
    columns += [(c, g[c][()].astype(np.float64)) for c in _STATE_COLUMNS if c in g]
    for name, values in columns:
        if len(values) != n:
            raise EcoFormatError(f"{path}: {group}/{name} has {len(values)} entries, species_id {n}")
    data = np.empty(n, dtype=[(name, values.dtype) for name, values in columns])
    for name, values in columns:
        data[name] = values
    units = {name: (unit_of(g[name], PLANT_UNITS[name]) if name in g else PLANT_UNITS[name]) for name, _ in columns}
    attrs = {k: decode(g.attrs[k]) for k in g.attrs.keys()}
    return Plants(data, names, units, group, attrs)

"""Grids (rasters) with world coordinates: the layout of docs/hdf5.md "Grids"."""

import numpy as np

from ._h5 import EcoFormatError, attrs_of, decode

MONTH_NAMES = ("Jan", "Feb", "Mar", "Apr", "May", "Jun", "Jul", "Aug", "Sep", "Oct", "Nov", "Dec")


class Grid:
    """One raster, or a monthly stack, with its coordinates and units.

    ``values``: numpy array ``[y][x]`` (a stack ``[month][y][x]``), in the file's order:
    **row 0 is the southern row** (y grows with the row index), so
    ``matplotlib.pyplot.imshow(g.values, origin="lower", extent=g.extent)`` draws it north-up.
    ``x``, ``y``: world coordinates in metres of the cell centres (``len(x)`` columns,
    ``len(y)`` rows): x = origin_x_m + (ix + 0.5) cell_size_m, likewise y.
    ``months``: 1..12 for a monthly stack (plane 0 = January), else None.
    ``units``: the dataset's ``units`` attribute. ``attrs``: all of its attributes.
    """

    def __init__(self, values, cell_size_m, origin_x_m, origin_y_m, units, name="", attrs=None, months=None):
        self.values = values
        self.cell_size_m = float(cell_size_m)
        self.origin_x_m = float(origin_x_m)
        self.origin_y_m = float(origin_y_m)
        self.units = units
        self.name = name
        self.attrs = dict(attrs or {})
        self.months = months
        ny, nx = values.shape[-2], values.shape[-1]
        self.x = self.origin_x_m + (np.arange(nx) + 0.5) * self.cell_size_m
        self.y = self.origin_y_m + (np.arange(ny) + 0.5) * self.cell_size_m

    @property
    def shape(self):
        return self.values.shape

    @property
    def extent(self):
        """(x_min, x_max, y_min, y_max) of the cell edges, metres: matplotlib's ``extent``."""
        ny, nx = self.values.shape[-2], self.values.shape[-1]
        return (self.origin_x_m, self.origin_x_m + nx * self.cell_size_m,
                self.origin_y_m, self.origin_y_m + ny * self.cell_size_m)

    @property
    def crs_wkt(self):
        """The coordinate reference system (WKT) of a grid made from a georeferenced input, else None."""
        return self.attrs.get("crs_wkt")

    def north_up(self):
        """The values with row 0 the NORTHERN row (as images and ESRI ASCII grids store them)."""
        return self.values[..., ::-1, :]

    def month(self, month):
        """One month (1 = January .. 12) of a monthly stack, as a 2-D Grid."""
        if self.months is None:
            raise ValueError(f"{self.name}: not a monthly stack")
        if not 1 <= month <= len(self.months):
            raise ValueError(f"{self.name}: month {month} out of 1..{len(self.months)}")
        return Grid(self.values[month - 1], self.cell_size_m, self.origin_x_m, self.origin_y_m,
                    self.units, f"{self.name}[month {month}]", self.attrs)

    def annual_mean(self):
        """The mean over the months of a monthly stack, as a 2-D Grid (same units)."""
        if self.months is None:
            raise ValueError(f"{self.name}: not a monthly stack")
        return Grid(self.values.mean(axis=0), self.cell_size_m, self.origin_x_m, self.origin_y_m,
                    self.units, f"{self.name} (annual mean)", self.attrs)

    def cell_of(self, x_m, y_m):
        """(ix, iy) of the cell containing world point(s) (x_m, y_m); arrays allowed.
        Points outside the grid raise ValueError."""
        ix = np.floor((np.asarray(x_m, dtype=float) - self.origin_x_m) / self.cell_size_m).astype(int)
        iy = np.floor((np.asarray(y_m, dtype=float) - self.origin_y_m) / self.cell_size_m).astype(int)
        ny, nx = self.values.shape[-2], self.values.shape[-1]
        if np.any((ix < 0) | (ix >= nx) | (iy < 0) | (iy >= ny)):
            raise ValueError(f"{self.name}: point outside the grid {self.extent}")
        return ix, iy

    def at(self, x_m, y_m):
        """The value(s) of the cell(s) containing world point(s) (x_m, y_m) (for a stack:
        the 12 monthly values last)."""
        ix, iy = self.cell_of(x_m, y_m)
        v = self.values[..., iy, ix]
        return np.moveaxis(v, 0, -1) if self.months is not None else v

    def to_pandas(self):
        """A long pandas DataFrame: columns x_m, y_m (cell centres), month (stacks only)
        and ``value``; ``df.attrs["units"]`` holds the units. Needs pandas."""
        import pandas as pd
        yy, xx = np.meshgrid(self.y, self.x, indexing="ij")
        if self.months is None:
            df = pd.DataFrame({"x_m": xx.ravel(), "y_m": yy.ravel(), "value": self.values.ravel()})
        else:
            n = len(self.months)
            df = pd.DataFrame({"month": np.repeat(np.asarray(self.months), xx.size),
                               "x_m": np.tile(xx.ravel(), n), "y_m": np.tile(yy.ravel(), n),
                               "value": self.values.reshape(n, -1).ravel()})
        df.attrs["units"] = self.units
        return df

    def __repr__(self):
        kind = f"{len(self.months)} months x " if self.months is not None else ""
        ny, nx = self.values.shape[-2], self.values.shape[-1]
        return (f"Grid({self.name!r}: {kind}{ny} x {nx} cells of {self.cell_size_m:g} m from "
                f"({self.origin_x_m:.10g}, {self.origin_y_m:.10g}), units {self.units!r})")


def read_grid(f, name, path, monthly=None):
    """A grid dataset of an open h5py file. ``monthly``: True for a 12-plane stack, False
    for 2-D, None to take what the file has (3-D = monthly)."""
    if name not in f:
        raise EcoFormatError(f"{path}: dataset {name} is missing")
    ds = f[name]
    attrs = attrs_of(ds)
    for key in ("cell_size_m", "origin_x_m", "origin_y_m"):
        if key not in attrs:
            raise EcoFormatError(f"{path}: {name}: grid attribute '{key}' is missing")
    order = attrs.get("row_order", "south_to_north")
    if order != "south_to_north":
        raise EcoFormatError(f"{path}: {name}: row_order '{order}' found, expected 'south_to_north'")
    values = ds[()]
    if monthly is None:
        monthly = values.ndim == 3
    want = 3 if monthly else 2
    if values.ndim != want:
        raise EcoFormatError(f"{path}: {name}: a {values.ndim}-D dataset, expected {want}-D")
    months = np.arange(1, values.shape[0] + 1) if monthly else None
    return Grid(values, attrs["cell_size_m"], attrs["origin_x_m"], attrs["origin_y_m"], attrs.get("units"),
                name, attrs, months)

"""HDF5 plumbing shared by the readers: opening, format checks, attributes, units.

Everything here follows docs/hdf5.md; the table of formats and the schema versions this
package reads is ``FORMATS``. Bump it together with the C++ writer's version.
"""

import h5py
import numpy as np

#: Every kind of file eco writes (root attribute ``format``) and the ``schema_version``
#: values this package reads, with the command that writes it. Versions not listed are
#: refused: a newer file may have moved or renamed what the readers rely on.
FORMATS = {
    "eco-terrain": {"versions": (1,), "written_by": "eco terrain generate / eco terrain convert"},
    "eco-chm": {"versions": (1,), "written_by": "eco chm generate"},
    "eco-abiotics": {"versions": (1, 2), "written_by": "eco abiotics"},
    "eco-canopy": {"versions": (1, 2), "written_by": "eco canopy"},
    "eco-simulation": {"versions": (1, 2), "written_by": "eco simulate"},
    "eco-biome-db": {"versions": (2, 3, 4, 5), "written_by": "eco analyse"},
    "eco-scene": {"versions": (1,), "written_by": "eco synth"},
}


class EcoFormatError(ValueError):
    """A file is not of the expected kind or schema version (or not an eco file at all).

    The message names the file, what was found and what was expected.
    """


def decode(value):
    """An HDF5 attribute or small dataset value as plain Python: ``str`` for strings
    (fixed- and variable-length, bytes decoded as UTF-8), ``int``/``float`` for scalars,
    numpy arrays for numeric arrays and lists of ``str`` for string arrays."""
    if isinstance(value, bytes):
        return value.decode("utf-8", errors="replace")
    if isinstance(value, np.ndarray):
        if value.dtype.kind in ("S", "O", "U"):
            return [decode(v) for v in value.tolist()]
        if value.shape == ():
            return value.item()
        return value
    if isinstance(value, np.generic):
        return value.item()
    return value


#: Attributes of HDF5's dimension scales (the library's bookkeeping: references between a
#: grid and its coordinate datasets x_m, y_m, month), left out of ``attrs_of``.
DIMENSION_SCALE_ATTRS = frozenset({"DIMENSION_LIST", "REFERENCE_LIST", "CLASS", "NAME", "DIMENSION_LABELS"})


def attrs_of(obj):
    """All attributes of an HDF5 object as a dict of plain Python values (without the
    dimension-scale bookkeeping, ``DIMENSION_SCALE_ATTRS``)."""
    return {key: decode(obj.attrs[key]) for key in obj.attrs.keys() if key not in DIMENSION_SCALE_ATTRS}


def is_dimension_scale(dataset):
    """True for a coordinate dataset (x_m, y_m, month, ...) that files since issue 31 keep
    beside their grids as an HDF5 dimension scale: not a column of a table."""
    return decode(dataset.attrs.get("CLASS", b"")) == "DIMENSION_SCALE"


def read_strings(dataset):
    """A dataset of fixed- or variable-length strings as a list of ``str``."""
    return [decode(v) for v in np.asarray(dataset[()]).reshape(-1).tolist()]


def open_checked(path, expected_format, allow_unmarked_with=None):
    """Open ``path`` read-only and check its root ``format`` and ``schema_version``.

    ``expected_format`` is one of ``FORMATS`` (or a tuple of them). Returns
    ``(h5py.File, format, schema_version)``; the caller closes the file.
    ``allow_unmarked_with``: a dataset path whose presence makes a file without a
    ``format`` attribute acceptable (terrain and CHM files written before eco marked
    them, which eco's own readers still take); their version is reported as 0.
    """
    expected = (expected_format,) if isinstance(expected_format, str) else tuple(expected_format)
    try:
        f = h5py.File(path, "r")
    except OSError as e:
        raise EcoFormatError(f"{path}: cannot open as HDF5 ({e})") from None
    try:
        fmt, version = _check(f, path, expected, allow_unmarked_with)
    except Exception:
        f.close()
        raise
    return f, fmt, version


def _check(f, path, expected, allow_unmarked_with):
    want = " or ".join(f"'{e}'" for e in expected)
    if "format" not in f.attrs:
        if allow_unmarked_with and allow_unmarked_with in f:
            return expected[0], 0
        raise EcoFormatError(f"{path}: not an eco file of the expected kind: root attribute 'format' "
                             f"is missing (expected {want})")
    fmt = decode(f.attrs["format"])
    if fmt not in FORMATS:
        raise EcoFormatError(f"{path}: unknown format '{fmt}' (this ecotoolkit reads {', '.join(sorted(FORMATS))})")
    if fmt not in expected:
        raise EcoFormatError(f"{path}: format '{fmt}' ({FORMATS[fmt]['written_by']}), expected {want}")
    if "schema_version" not in f.attrs:
        raise EcoFormatError(f"{path}: root attribute 'schema_version' is missing (format '{fmt}', "
                             f"versions read: {_versions(fmt)})")
    raw = decode(f.attrs["schema_version"])
    try:
        version = int(raw)
    except (TypeError, ValueError):
        raise EcoFormatError(f"{path}: schema_version {raw!r} is not an integer (format '{fmt}')") from None
    if version not in FORMATS[fmt]["versions"]:
        raise EcoFormatError(f"{path}: format '{fmt}' schema_version {version} found, this ecotoolkit reads "
                             f"version {_versions(fmt)}; update python/ecotoolkit (or re-run "
                             f"{FORMATS[fmt]['written_by']} with a matching eco)")
    return fmt, version


def _versions(fmt):
    return ", ".join(str(v) for v in FORMATS[fmt]["versions"])


def sniff_format(path):
    """The root ``format`` attribute of an HDF5 file, or None when it has none."""
    try:
        with h5py.File(path, "r") as f:
            return decode(f.attrs["format"]) if "format" in f.attrs else None
    except OSError as e:
        raise EcoFormatError(f"{path}: cannot open as HDF5 ({e})") from None


def unit_of(dataset, documented):
    """The dataset's own ``units`` attribute when it has one, else the documented unit
    (docs/hdf5.md, docs/database.md, core/plants.h): files written before every dataset
    carried units get the unit the writer used."""
    if "units" in dataset.attrs:
        return decode(dataset.attrs["units"])
    return documented

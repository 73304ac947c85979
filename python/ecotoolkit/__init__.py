"""ecotoolkit: read the HDF5 files of the eco plant-ecosystem toolkit into numpy arrays.

Every reader checks the file's root ``format`` and ``schema_version`` attributes and
refuses a file of another kind or an unknown version (EcoFormatError). Grids come with
world coordinates in metres (cell centres) and units; plant tables as numpy structured
arrays with a unit per column; ``to_pandas()`` where pandas is installed. See docs/python.md.
"""

from ._h5 import FORMATS, EcoFormatError
from .database import Database, Region, read_database
from .files import (Abiotics, Canopy, Census, Chm, Disturbance, EcoFile, Scene, Simulation, Terrain, open, read_abiotics,
                    read_canopy, read_chm, read_scene, read_simulation, read_terrain)
from .grid import MONTH_NAMES, Grid
from .plants import PLANT_UNITS, Plants

__all__ = ["FORMATS", "EcoFormatError", "EcoFile", "Grid", "Plants", "Census", "Disturbance", "Region", "MONTH_NAMES",
           "PLANT_UNITS", "Terrain", "Chm", "Abiotics", "Canopy", "Simulation", "Database", "Scene", "open",
           "read_terrain", "read_chm", "read_abiotics", "read_canopy", "read_simulation", "read_database",
           "read_scene"]

__version__ = "0.1.0"

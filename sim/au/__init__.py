"""AU tables (data files ``human.toml``, ``dog.toml``) and their compiled form for one head."""

from servoface.sim.au.mapping import AUMapping, canonical_au_name, check_au
from servoface.sim.au.table import AU_DIR, AUAction, AUEntry, AUTable, au_table_path, load_au_table

__all__ = [
    "AU_DIR",
    "AUAction",
    "AUEntry",
    "AUMapping",
    "AUTable",
    "au_table_path",
    "canonical_au_name",
    "check_au",
    "load_au_table",
]

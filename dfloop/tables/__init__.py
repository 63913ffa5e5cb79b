"""dfloop.tables: adaptive tables of expensive complex functions, and their disk cache.

Generic: nothing here knows what is tabulated. A *sampler* maps points to :class:`Samples` (value, regime
label, regular flag, spreads); :class:`Table1D` refines where the function varies fast and brackets every jump
between regimes, block by block on a fixed lattice (content independent of the order of requests);
:class:`Table2D` stacks such lines along a second coordinate; :class:`TableStore` builds a table lazily over
the window asked for, with a progress bar, and keeps it on disk (:mod:`dfloop.tables.cache`: one checksummed
``.npz`` per key, atomic writes). :class:`dfloop.impact.DynamicBacklash` is the user of all of it.
"""
from .cache import cache_dir
from .store import TableStore
from .table1d import Samples, Table1D, TableSettings, TableValues, settings_dict
from .table2d import Table2D

__all__ = ["Samples", "Table1D", "Table2D", "TableSettings", "TableValues", "TableStore", "cache_dir",
           "settings_dict"]

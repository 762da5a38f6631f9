"""CSV logs of a car: a folder of CSV files, a column mapping, and the import with its quality report.

:func:`import_csv_log` reads what a :class:`CsvLogSpec` maps (pose, speed, yaw rate, commands;
units; time columns), keeps a :class:`~rkmpc.learning.data.window.TimeWindow`, takes out pose jumps,
splits episodes at gaps and resamples onto the control period with the bag import's resampler;
it returns the data set and its :class:`~rkmpc.learning.data.quality.QualityReport`. Specs come
from TOML files or presets (:func:`csv_spec`; ``friction-maps``).
"""

from __future__ import annotations

from rkmpc.learning.data.logs.importer import LogImport, import_csv_log
from rkmpc.learning.data.logs.presets import FRICTION_MAPS, PRESETS
from rkmpc.learning.data.logs.spec import (
    CommandSource,
    CsvLogSpec,
    PoseSource,
    TimeColumns,
    ValueSource,
)
from rkmpc.learning.data.logs.specfile import csv_spec, load_csv_spec, spec_toml

__all__ = [
    "FRICTION_MAPS",
    "PRESETS",
    "CommandSource",
    "CsvLogSpec",
    "LogImport",
    "PoseSource",
    "TimeColumns",
    "ValueSource",
    "csv_spec",
    "import_csv_log",
    "load_csv_spec",
    "spec_toml",
]

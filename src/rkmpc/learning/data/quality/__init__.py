"""Data-quality reports: what a recording or a data set shows about its sensors.

:class:`QualityReport` (with ``to_json()`` and ``to_markdown()``) is made at import
(:func:`rkmpc.learning.data.logs.import_csv_log`) and, for any data set, by
:func:`dataset_quality`.
"""

from __future__ import annotations

from rkmpc.learning.data.quality.dataset import dataset_quality
from rkmpc.learning.data.quality.report import QualityReport

__all__ = ["QualityReport", "dataset_quality"]

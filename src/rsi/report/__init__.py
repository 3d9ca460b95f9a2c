"""View layer: result records to files (pictures, ROC plots, flaw tables, summaries); runs no algorithm.

Every file is written atomically (a temporary file in the same folder, then ``os.replace``), so a reader
never sees a half-written result.
"""

from __future__ import annotations

from rsi.report.batch import write_batch_report
from rsi.report.deeppcb import write_deeppcb_report
from rsi.report.writers import write_demo_report, write_pair_report, write_roc_report

__all__ = [
    "write_batch_report",
    "write_deeppcb_report",
    "write_demo_report",
    "write_pair_report",
    "write_roc_report",
]

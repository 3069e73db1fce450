"""Many photos at once: ``photo3d batch`` as a library (see :func:`run_batch`).

Example:
    >>> from photo3d.batch import ENGINES
    >>> ENGINES
    ('local', 'ray')
"""

from photo3d.batch.jobs import MakeOptions, PhotoJob, find_photos
from photo3d.batch.manifest import MANIFEST, PhotoResult, read_manifest
from photo3d.batch.run import ENGINES, BatchSummary, run_batch
from photo3d.batch.worker import PhotoMaker
from photo3d.output import is_complete

__all__ = ["ENGINES", "MANIFEST", "BatchSummary", "MakeOptions", "PhotoJob", "PhotoMaker",
           "PhotoResult", "find_photos", "is_complete", "read_manifest", "run_batch"]

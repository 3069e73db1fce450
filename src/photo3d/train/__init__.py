"""Training the learned inpainter's three nets (paper, Sec. 3.3; supplement,
"Training objective" and "Training details"); extra ``photo3d[learned]``.

- :mod:`photo3d.train.pairs`: context/synthesis region pairs from an image's depth,
  found by the pipeline's own stages.
- :mod:`photo3d.train.dataset`: training folders (photos, depth by stem, shape-only
  maps), preparation and its cache.
- :mod:`photo3d.train.samples`: a pair pasted onto a *different* photo, resized,
  flipped, swapped; net inputs built by the learned backend's own code.
- :mod:`photo3d.train.losses`: colour, depth and EdgeConnect objectives.
- :mod:`photo3d.train.trainer`: config, nets, Adam, one step, checkpoints.
- :mod:`photo3d.train.run`: the training loop (resume, loss CSV, sample grids, export).
- :mod:`photo3d.train.run_folder`: a run's folder (layout, checks, lock, checkpoints).
- :mod:`photo3d.train.grid`, :mod:`photo3d.train.builtin`: sample grids; a training
  folder from offline data.

Example:
    >>> from photo3d.train import TrainConfig
    >>> TrainConfig("color", width=0.25, levels=5, size=128).net_config()
    {'levels': 5, 'width': 0.25, 'center': True}
"""

from photo3d.errors import MissingExtra

try:
    import torch  # noqa: F401
except ImportError as err:  # pragma: no cover - depends on the environment
    raise MissingExtra("photo3d.train", "PyTorch", "learned", module="torch") from err

from photo3d.train.builtin import write_builtin
from photo3d.train.dataset import (
    Target,
    TrainingData,
    TrainingFile,
    find_training_files,
    prepare_data,
)
from photo3d.train.pairs import RegionPair, extract_region_pairs
from photo3d.train.run import TrainResult, train
from photo3d.train.run_folder import checkpoints
from photo3d.train.samples import Sample, make_batch, make_sample
from photo3d.train.trainer import TrainConfig, Trainer, parameter_count, to_tensors

__all__ = [
    "RegionPair",
    "Sample",
    "Target",
    "TrainConfig",
    "TrainResult",
    "Trainer",
    "TrainingData",
    "TrainingFile",
    "checkpoints",
    "extract_region_pairs",
    "find_training_files",
    "make_batch",
    "make_sample",
    "parameter_count",
    "prepare_data",
    "to_tensors",
    "train",
    "write_builtin",
]

"""Fine-tune the shipped compact colour net as a *centred* net (issue 14).

The compact colour net of issue 5 filled every hole with its training photos'
orange-brown. This continues its training with the colour centred on the context's
mean (``PartialConvUNet(center=True)``) and the colour channels of each training crop
in a random order (``photo3d.train.samples``), starting from the shipped weights
(same architecture and keys, fresh Adam state), on the same built-in data and
settings as ``train_compact.sh``.

Usage: nice python scripts/training/finetune_color.py RUN_DIR [--steps 400] [--threads 1]
Then: cp RUN_DIR/color.safetensors src/photo3d/nets/compact/
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

from photo3d.inpaint.learned import bundled_weights
from photo3d.nets.weights import read_safetensors
from photo3d.train import (
    TrainConfig,
    Trainer,
    find_training_files,
    prepare_data,
    train,
    write_builtin,
)
from photo3d.train.run_folder import checkpoints

START = 1250
"""Steps the shipped colour net was trained for (``training.json``)."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("--steps", type=int, default=400, help="steps added to the 1250")
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    config = TrainConfig("color", width=0.25, levels=5, size=128, batch=8, lr=3e-4,
                         steps=START + args.steps, checkpoint_every=100, sample_every=100,
                         center=True)
    folder = args.run / "builtin"
    if not (folder / "images").is_dir():
        side = config.working_size
        write_builtin(folder, scenes=48, width=side, height=side * 3 // 4)
    files = find_training_files(folder / "images", depth=folder / "depth",
                                shapes=folder / "shapes")
    data = prepare_data(files, crop=config.size, region_size=config.working_size,
                        seed=config.seed, cache=args.run / "data")
    if not checkpoints(args.run):
        trainer = Trainer(config, device="cpu")
        state, _ = read_safetensors(bundled_weights() / "color.safetensors")
        trainer.net.load_state_dict(state, strict=True)
        trainer.save(args.run / "checkpoints" / f"step_{START:07d}", START)
    t = time.perf_counter()

    def report(step: int, total: int, terms: dict[str, float]) -> None:
        if step % 25 == 0:
            print(f"step {step}/{total} {time.perf_counter() - t:.0f}s "
                  f"synthesis {terms['synthesis']:.4f} total {terms['total']:.4f}", flush=True)

    result = train(data, args.run, config, device="cpu", progress=report)
    print(f"done: step {result.step}, {result.seconds:.0f} s, weights {result.weights}")


if __name__ == "__main__":
    main()

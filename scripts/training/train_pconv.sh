#!/bin/bash
# Train the paper's partial-convolution colour U-Net from scratch on real photos, compact
# (width 0.25, 5 levels, 0.73 M parameters; the shape of the shipped nets), with the
# paper's colour loss, and score it on held-out photos every 250 steps (issue 28;
# docs/learned.md, "The refine colour net"). Data as scripts/training/train_refine.sh:
# data/photos/train (scripts/data/fetch_photos.py), region shapes from 64 built-in
# synthetic scenes at 640 px, 24 photos of data/photos/heldout for the score.
#
# On one CPU core (--threads 1) a step takes about 2.2 s. Running the same command again
# resumes from the last checkpoint (RUN/checkpoints/, the last two kept, 11.7 MB each).
# To go on from the checkpoint in the repository:
#   mkdir -p RUN/checkpoints && cp scripts/training/runs/pconv/{config.json,*.csv} RUN/ &&
#   cp -r scripts/training/runs/pconv/checkpoint RUN/checkpoints/step_0002000
# (the step is in checkpoint/state.json), then run this script with RUN.
#
# Usage: scripts/training/train_pconv.sh [RUN_DIR] [STEPS]   (from the repository root)
set -euo pipefail
RUN=${1:-/work/runs/pconv}
STEPS=${2:-200000}
exec nice -n 10 photo3d train color --images data/photos/train \
  --heldout data/photos/heldout --heldout-photos 24 \
  --shape-scenes 64 --region-size 640 --size 128 --batch 8 --width 0.25 --levels 5 \
  --lr 3e-4 --steps "$STEPS" --checkpoint-every 250 --sample-every 1000 --heldout-every 250 \
  --threads 1 -q --out "$RUN"

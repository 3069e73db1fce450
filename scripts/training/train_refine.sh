#!/bin/bash
# Train the refine colour net (issue 28): a gated-convolution U-Net that adds a residual
# to the diffusion fill (src/photo3d/nets/refine.py; docs/learned.md, "The refine colour
# net"). 1.49 M parameters (channels 16, 4 levels, 4 residual blocks at 1/16 scale).
#
# Data: real photos without depth (data/photos/train, see data/photos/SOURCES.tsv);
# region shapes from 64 built-in synthetic scenes (seeds from 1000 on; never the
# motorcycle, whose shapes the held-out score uses), grown at 640 px like the held-out
# benchmark's. The net ignores its edge channel (--no-edges): photos without depth
# never show it an edge. Losses: the paper's colour loss (L1 context + 6 L1 hole +
# 0.05 VGG-16 perceptual + 120 style + 0.01 TV). Crop 128, batch 4, Adam lr 3e-4.
# Every 250 steps the net is scored on 24 held-out photos (data/photos/heldout; the
# protocol of `photo3d eval --heldout`) into RUN/heldout.csv; plot it with
#   python scripts/training/plot_training.py RUN --out docs/img/training_refine.png
#
# On one CPU core (--threads 1) a step takes about 1.5 s when the core is free. Running
# the same command again resumes from the last checkpoint (RUN/checkpoints/, the last
# two kept; weights + Adam state about 18 MB); --steps is the total to reach.
# On a GPU: add --device cuda and raise --batch (e.g. 16) and --size (e.g. 256); a new
# --size or --batch changes the data, not the net, so a run may continue with them.
# To add the adversarial term later (PatchGAN, hinge), resume with --adversarial 0.1.
#
# Usage: scripts/training/train_refine.sh [RUN_DIR] [STEPS]   (from the repository root)
# Then:  cp RUN_DIR/color.safetensors WEIGHTS_DIR/  (with an edge and a depth net)
set -euo pipefail
RUN=${1:-/work/runs/refine}
STEPS=${2:-200000}
exec nice -n 10 photo3d train color --arch refine --no-edges \
  --images data/photos/train --heldout data/photos/heldout --heldout-photos 24 \
  --shape-scenes 64 --region-size 640 --size 128 --batch 4 --lr 1e-3 \
  --steps "$STEPS" --checkpoint-every 250 --sample-every 1000 --heldout-every 250 \
  --threads 1 -q --out "$RUN"

#!/bin/bash
# Train the compact inpainting nets shipped in src/photo3d/nets/compact/ (issue 5).
# Width 0.25, 5 U-Net levels / 4 edge blocks, crop 128, batch 8, built-in offline data,
# lr 3e-4 (the paper's 1e-4 is for days on a GPU; this is a short CPU budget).
# Each net trains alone on one core (--threads 1); run two at once on a 2-core CPU:
#   scripts/training/train_compact.sh RUNS color &  scripts/training/train_compact.sh RUNS depth-edge
# Rerunning resumes; raise the step counts (2nd/3rd argument) to train longer.
# Then: cp RUNS/{edge,depth,color}/*.safetensors src/photo3d/nets/compact/
set -euo pipefail
RUNS=${1:?usage: train_compact.sh RUNS_DIR color|depth-edge [STEPS] [EDGE_STEPS]}
COMMON=(--images builtin --size 128 --batch 8 --width 0.25 --lr 3e-4 --threads 1
        --checkpoint-every 250 --sample-every 250 -q)
case "${2:?}" in
  color) photo3d train color "${COMMON[@]}" --levels 5 --out "$RUNS/color" --steps "${3:-1500}" ;;
  depth-edge)
    photo3d train depth "${COMMON[@]}" --levels 5 --out "$RUNS/depth" --steps "${3:-3000}"
    photo3d train edge "${COMMON[@]}" --blocks 4 --out "$RUNS/edge" --steps "${4:-2500}" ;;
  *) echo "unknown part $2 (color or depth-edge)" >&2; exit 2 ;;
esac

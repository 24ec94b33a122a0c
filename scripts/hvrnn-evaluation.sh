#!/usr/bin/env bash
# HVRNN's Table 2 and Fig. 4 on held-out data, from BVH files to the tables, one step after
# another (about 55 minutes on one CPU core with the defaults):
#   evaluation classifiers, loss classifiers, denoiser, then HVRNN and its ablations SL, NL
#   and NC, ERD and QuaterNet-style (`cpu` presets, trained on the denoised training takes),
#   then every model's classifier outputs and the IS / FID table with the t-SNE maps.
#
#   scripts/hvrnn-evaluation.sh [MOTION_DATA] [OUT]      (defaults: $MOTION_DATA, var/hvrnn)
#
# STEPS (training steps per model, default 3000; the `cpu` presets' schedules of KL
# annealing, classifier loss and word drop end at 1000) and THREADS (torch threads, default 1)
# are read from the environment. Each step's output goes to OUT/logs/NAME.log; a step whose
# output exists already is skipped, so an interrupted run continues where it stopped.
set -euo pipefail
cd "$(dirname "$0")/.."
DATA=${1:-${MOTION_DATA:?give the motion folder or set MOTION_DATA}}
OUT=${2:-var/hvrnn}
PY=${PYTHON:-.venv/bin/python}
STEPS=${STEPS:-3000}
THREADS=${THREADS:-1}
MODELS=$OUT/models
mkdir -p "$MODELS" "$OUT/logs"

step() {  # step NAME OUTPUT COMMAND...: run COMMAND unless OUTPUT exists
    local name=$1 output=$2; shift 2
    if [ -e "$output" ]; then echo "$(date +%T) $name: $output exists, skipped"; return; fi
    echo "$(date +%T) $name ..."
    local start=$SECONDS
    "$@" > "$OUT/logs/$name.log" 2>&1 || { echo "$name failed; see $OUT/logs/$name.log"; exit 1; }
    echo "$(date +%T) $name done in $((SECONDS - start)) s"
}

step eval-classifiers "$MODELS/eval-classifiers.safetensors" \
    $PY -m generation hvrnn-classifiers "$DATA" --seed 1 --threads "$THREADS" --out "$MODELS/eval-classifiers.safetensors"
# The classifiers of HVRNN's loss: a separate, smaller network (seed 0) on the same half.
step loss-classifiers "$MODELS/loss-classifiers.safetensors" \
    $PY -m generation hvrnn-classifiers "$DATA" --seed 0 --threads "$THREADS" --channels 32 64 64 --steps 600 \
    --out "$MODELS/loss-classifiers.safetensors"
step denoiser "$MODELS/denoiser.safetensors" \
    $PY -m generation hvrnn-denoiser "$DATA" --threads "$THREADS" --out "$MODELS/denoiser.safetensors"

TRAIN=(--steps "$STEPS" --eval-every 100 --threads "$THREADS" --denoiser "$MODELS/denoiser.safetensors")
LOSS=(--classifiers "$MODELS/loss-classifiers.safetensors")
for model in hvrnn:cpu hvrnn:cpu-SL hvrnn:cpu-NL hvrnn:cpu-NC erd:cpu quaternet:cpu; do
    kind=${model%%:*} preset=${model#*:}
    name=$kind-$preset
    extra=()
    [ "$kind" = hvrnn ] && [ "$preset" != cpu-NC ] && extra=("${LOSS[@]}")
    step "$name" "$MODELS/$name.safetensors" \
        $PY -m generation train "$DATA" --kind "$kind" --preset "$preset" "${extra[@]}" "${TRAIN[@]}" \
        --out "$MODELS/$name.safetensors"
done

step outputs "$OUT/outputs.npz" \
    $PY -m generation hvrnn-eval "$DATA" --classifiers "$MODELS/eval-classifiers.safetensors" \
    --checkpoint "HVRNN=$MODELS/hvrnn-cpu.safetensors" --checkpoint "HVRNN-SL=$MODELS/hvrnn-cpu-SL.safetensors" \
    --checkpoint "HVRNN-NL=$MODELS/hvrnn-cpu-NL.safetensors" --checkpoint "HVRNN-NC=$MODELS/hvrnn-cpu-NC.safetensors" \
    --checkpoint "ERD=$MODELS/erd-cpu.safetensors" --checkpoint "QuaterNet=$MODELS/quaternet-cpu.safetensors" \
    --out "$OUT/outputs.npz"
$PY -m analysis hvrnn-scores "$OUT/outputs.npz" --out "$OUT"

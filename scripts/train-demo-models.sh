#!/usr/bin/env bash
# The small models `make demo` ships beside MoGlow, trained again: `make demo-models`.
#
#   RNN  rnn    cpu preset, 400 steps,  the state with the lowest validation loss (.best)
#   VAE  vae    cpu preset, 1000 steps, the state with the lowest validation loss (.best)
#   BAD  moglow cpu preset, 15 steps,   the last state: visibly broken motion, the attention check
#
# on the data and split of the committed MoGlow (the locomotion of both Bandai-Namco
# folders, 4-s windows overlapping by three quarters, mirrored and reversed). Each run
# goes to var/demo-models/ (a run stopped part-way resumes), then the chosen state is
# copied to models/ and models/SHA256SUMS is written again. On two cores, about 10
# minutes with the machine to itself.
#
# Read from the environment:
#   DATA     motion folders joined with ':' (default both Bandai-Namco folders beside the project)
#   THREADS  torch threads, default 1
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
DATA=${DATA:-$(realpath ../shared/data/bandai-namco-1):$(realpath ../shared/data/bandai-namco-2-locomotion)}
IFS=: read -r -a FOLDERS <<< "$DATA"
THREADS=${THREADS:-1}
[[ $THREADS =~ ^[1-9][0-9]*$ ]] || { echo "THREADS must be a whole number of at least 1, got '$THREADS'" >&2; exit 2; }
# The options of the committed MoGlow (studyapp/demo.py, DATASET).
CONTENTS=walk,run,dash,walk-back,walk-left,walk-right,walk-turn-left,walk-turn-right
RUNS=var/demo-models
mkdir -p "$RUNS"

# train NAME KIND STEPS EVAL_EVERY CHOSEN(best|last)
train() {
    local name=$1 kind=$2 steps=$3 every=$4 chosen=$5
    local run="$RUNS/$name.safetensors"
    local resume=()
    [[ -f $run ]] && resume=(--resume)
    "$PY" -m generation train "${FOLDERS[@]}" --model "$kind" --preset cpu --contents "$CONTENTS" --reverse \
        --overlap 0.75 --steps "$steps" --eval-every "$every" --threads "$THREADS" --seed 0 --out "$run" "${resume[@]}"
    if [[ $chosen == best ]]; then cp "${run%.safetensors}.best.safetensors" "models/$name.safetensors"
    else cp "$run" "models/$name.safetensors"; fi
}

train rnn-cpu rnn 400 50 best
train vae-cpu vae 1000 100 best
train moglow-bad moglow 15 15 last
(cd models && sha256sum ./*.safetensors | sed 's| \./| |' > SHA256SUMS)
cat models/SHA256SUMS

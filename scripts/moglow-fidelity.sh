#!/usr/bin/env bash
# MoGlow's objective evaluation (Table 3 and Fig. 5 of its paper) on the locomotion of
# both Bandai-Namco datasets, from BVH files to the tables, one resumable step after another:
#   MoGlow (`cpu`), its MG-D ablation, and the RNN and VAE baselines, trained on the same
#   windows with the same split by take; the held-out natural takes (NAT); samples of every
#   model for the held-out takes' control and for synthetic controls, each beside the
#   held-out natural takes of the motion it asks for (NAT); `analysis objective`.
#
#   scripts/moglow-fidelity.sh [OUT]        (default var/fidelity)
#
# Read from the environment:
#   DATA            motion folders joined with ':' (default both Bandai-Namco folders beside
#                   the project)
#   MOGLOW_STEPS    default 40000: many hours on one core; a run stopped part-way continues
#                   from its checkpoint with --resume
#   BASELINE_STEPS  default 2000
#   MGD_STEPS, RNN_STEPS, VAE_STEPS
#                   where one model stops instead (defaults MOGLOW_STEPS, BASELINE_STEPS,
#                   BASELINE_STEPS)
#   THREADS         torch threads, default 1
#   SAMPLES         per control, default 4
#   SYSTEMS         the models to train and compare, default "MoGlow MG-D RNN VAE"
#   MGD_BRANCH      default 0: MG-D is trained from scratch without data dropout, as the paper
#                   did; a step N > 0 continues MoGlow's state at step N without data dropout
#                   instead, so the two differ only in what they learnt after it
# Each step's output goes to OUT/logs/NAME.log. Training steps resume; sampling and
# evaluation are redone every run, so the tables always describe the checkpoints as they are.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-var/fidelity}
PY=${PYTHON:-.venv/bin/python}
DATA=${DATA:-$(realpath ../shared/data/bandai-namco-1):$(realpath ../shared/data/bandai-namco-2-locomotion)}
IFS=: read -r -a FOLDERS <<< "$DATA"
MOGLOW_STEPS=${MOGLOW_STEPS:-40000}
BASELINE_STEPS=${BASELINE_STEPS:-2000}
MGD_STEPS=${MGD_STEPS:-$MOGLOW_STEPS}
RNN_STEPS=${RNN_STEPS:-$BASELINE_STEPS}
VAE_STEPS=${VAE_STEPS:-$BASELINE_STEPS}
THREADS=${THREADS:-1}
export OMP_NUM_THREADS=$THREADS  # sampling and evaluation too: a thread more than the free cores stalls them all
SAMPLES=${SAMPLES:-4}
MGD_BRANCH=${MGD_BRANCH:-0}
read -r -a SYSTEMS <<< "${SYSTEMS:-MoGlow MG-D RNN VAE}"
# Checked before anything runs: a bad SAMPLES would otherwise surface only after hours of training.
for setting in MOGLOW_STEPS BASELINE_STEPS MGD_STEPS RNN_STEPS VAE_STEPS MGD_BRANCH THREADS SAMPLES; do
    [[ ${!setting} =~ ^(0|[1-9][0-9]*)$ ]] || { echo "$setting must be a whole number, got '${!setting}'" >&2; exit 2; }
done
(( THREADS >= 1 && SAMPLES >= 1 )) || { echo "THREADS and SAMPLES must be at least 1" >&2; exit 2; }
declare -A KIND=([MoGlow]="moglow cpu $MOGLOW_STEPS 500" [MG-D]="moglow cpu-MG-D $MGD_STEPS 500"
                 [RNN]="rnn cpu $RNN_STEPS 100" [VAE]="vae cpu $VAE_STEPS 100")
for name in "${SYSTEMS[@]}"; do
    [ -n "${KIND[$name]:-}" ] || { echo "unknown system '$name' in SYSTEMS (MoGlow, MG-D, RNN, VAE)" >&2; exit 2; }
done
MGD_WANTED=$([[ " ${SYSTEMS[*]} " == *" MG-D "* ]] && echo 1 || echo 0)
if (( MGD_WANTED && MGD_BRANCH > 0 && MGD_STEPS <= MGD_BRANCH )); then
    echo "MGD_STEPS=$MGD_STEPS must be past MGD_BRANCH=$MGD_BRANCH, where MG-D leaves MoGlow's run" >&2; exit 2
fi
CONTENTS=walk,run,dash,walk-back,walk-left,walk-right,walk-turn-left,walk-turn-right
SYNTHETIC=(walk-straight walk-circle sidestep-left walk-backward stand-still)
MODELS=$OUT/models
mkdir -p "$MODELS" "$OUT/logs"

run() {  # run NAME COMMAND...: COMMAND's output into OUT/logs/NAME.log
    local name=$1; shift
    echo "$(date +%T) $name ..."
    local start=$SECONDS
    local status=0
    "$@" > "$OUT/logs/$name.log" 2>&1 || status=$?
    # The step's own exit status goes on: 2 when the data or a setting was refused.
    (( status == 0 )) || { echo "$name failed; see $OUT/logs/$name.log" >&2; exit "$status"; }
    echo "$(date +%T) $name done in $((SECONDS - start)) s"
}

train() {  # train NAME KIND PRESET STEPS EVAL_EVERY [OPTION...]: trains, or continues, MODELS/NAME.safetensors
    local name=$1 kind=$2 preset=$3 steps=$4 every=$5 resume=()
    shift 5
    [ -e "$MODELS/$name.safetensors" ] && resume=(--resume)
    # Sec. 4.2 of the paper: mirroring and time reversal; 75 % window overlap because the
    # dataset-2 takes are short (about 5 s).
    run "train-$name" $PY -m generation train "${FOLDERS[@]}" --model "$kind" --preset "$preset" \
        --contents "$CONTENTS" --reverse --overlap 0.75 --steps "$steps" --eval-every "$every" \
        --threads "$THREADS" --out "$MODELS/$name.safetensors" "${resume[@]}" "$@"
}

copy_checkpoint() {  # copy_checkpoint FROM TO: a checkpoint and its optimiser state (both without .safetensors)
    cp "$1.safetensors" "$2.safetensors"
    cp "$1.optim.safetensors" "$2.optim.safetensors"
}

branch_mg_d() {  # MG-D starts as MoGlow's state at step MGD_BRANCH (kept as MoGlow-stepN)
    local kept=$MODELS/MoGlow-step$MGD_BRANCH
    [ -e "$MODELS/MG-D.safetensors" ] && return
    if [ ! -e "$kept.safetensors" ]; then
        train MoGlow moglow cpu "$MGD_BRANCH" 500
        local step
        step=$($PY -c "import sys; from generation.checkpoints.checkpoint import read_meta; print(read_meta(sys.argv[1]).step)" "$MODELS/MoGlow.safetensors")
        if [ "$step" != "$MGD_BRANCH" ]; then
            echo "MoGlow is at step $step, past MGD_BRANCH=$MGD_BRANCH, and its state there was not kept;" \
                 "set MGD_BRANCH to 0 (MG-D from scratch) or remove $MODELS/MoGlow.safetensors" >&2
            exit 2
        fi
        copy_checkpoint "$MODELS/MoGlow" "$kept"
    fi
    copy_checkpoint "$kept" "$MODELS/MG-D"
}

if (( MGD_WANTED && MGD_BRANCH > 0 )); then
    branch_mg_d
    KIND[MG-D]="moglow cpu $MGD_STEPS 500 --set dropout=0"
fi
for name in "${SYSTEMS[@]}"; do
    train "$name" ${KIND[$name]}
done

rm -rf "$OUT/held-out" "$OUT/synthetic" "$OUT/natural"
# The held-out takes are sampled as the authors' code samples a test take: from the mean
# pose on the take's own control from its first frame, the first second discarded (the
# warm-up runs on it); NAT is the same frames of the takes.
run natural $PY -m generation natural "${FOLDERS[@]}" --contents "$CONTENTS" --lead-in 1 --out "$OUT/held-out/NAT"
# Each synthetic control is compared with the held-out takes of the natural motion it asks for.
declare -A NATURAL_FOR=([walk-straight]=walk [walk-circle]=walk-turn-left [sidestep-left]=walk-left
                        [walk-backward]=walk-back [stand-still]=walk)
for content in $(printf '%s\n' "${NATURAL_FOR[@]}" | sort -u); do
    run "natural-$content" $PY -m generation natural "${FOLDERS[@]}" --contents "$content" --out "$OUT/natural/$content"
done
for name in "${SYSTEMS[@]}"; do
    run "sample-$name" $PY -m generation sample "$MODELS/$name.safetensors" -c held-out --data "${FOLDERS[@]}" \
        --lead-in 1 --n "$SAMPLES" --seed 1 --out "$OUT/held-out/$name"
    for control in "${SYNTHETIC[@]}"; do
        run "sample-$control-$name" $PY -m generation sample "$MODELS/$name.safetensors" -c "$control" \
            --n "$SAMPLES" --seed 1 --out "$OUT/synthetic/$control/$name"
    done
done
# Footsteps from the toes: a walker's heel lifts while its toes stay planted (natural
# walking's lower heel moves at about 40 cm/s, its lower toe at about 8).
run objective-held-out $PY -m analysis objective "$OUT/held-out" --foot-kind toe --out "$OUT/tables/held-out"
for control in "${SYNTHETIC[@]}"; do
    cp -r "$OUT/natural/${NATURAL_FOR[$control]}" "$OUT/synthetic/$control/NAT"
    run "objective-$control" $PY -m analysis objective "$OUT/synthetic/$control" --foot-kind toe --out "$OUT/tables/$control"
done
for name in "${SYSTEMS[@]}"; do
    run "evaluate-$name" $PY -m generation evaluate "$MODELS/$name.safetensors" --data "${FOLDERS[@]}"
done
echo "tables in $OUT/tables; held-out losses in $OUT/logs/evaluate-*.log"

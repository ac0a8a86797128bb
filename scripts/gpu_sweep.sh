#!/usr/bin/env bash
# Several DanceNet training configurations side by side on a lent CUDA GPU for a fixed wall time, then each
# validated on the same machine, so a short loan gives a validation table. Never needed: the CPU
# path (`dancenet train dancenet`) is the default and this only runs the same command several times at once.
#
#   bash scripts/gpu_sweep.sh PACK MINUTES OUT CONFIGS
#
# PACK: `dancenet data pack` (the training and validation songs' features; the GPU machine has no madmom and
# no data folder). CONFIGS: a file of lines `name: options of dancenet train dancenet` (# comments). Every run
# holds the validation songs out (--validation) and uses the pack; OUT gets each run's weights (NAME.pt) and
# one sweep.tar.gz with the logs and validation tables. Needs torch, numpy, scipy and scikit-learn, nothing else.
set -uo pipefail
cd "$(dirname "$0")/.."
PACK=$1 MINUTES=$2 OUT=$3 CONFIGS=$4
RUNS=runs/sweep
mkdir -p "$RUNS" "$OUT"
export PYTHONPATH=$PWD${PYTHONPATH:+:$PYTHONPATH} PYTHONUNBUFFERED=1 OMP_NUM_THREADS=2
dancenet() { python3 -m dancenet_core.cli "$@"; }
nvidia-smi --query-gpu=name,memory.total --format=csv,noheader 2>/dev/null || echo "no GPU: the runs use the CPU"

names=()
while IFS= read -r line; do
    [[ -z "${line// }" || "$line" == \#* ]] && continue
    name=${line%%:*}; opts=${line#*:}
    names+=("$name")
    # shellcheck disable=SC2086  # the options are words
    dancenet train dancenet --pack "$PACK" --validation --minutes "$MINUTES" --steps 1000000 \
        --out "$RUNS/$name" $opts >"$RUNS/$name.train.log" 2>&1 &
done <"$CONFIGS"
wait
for name in "${names[@]}"; do
    echo "== $name: $(tail -n 1 "$RUNS/$name/log.jsonl" 2>/dev/null || tail -n 3 "$RUNS/$name.train.log")"
done

# The weights come back first, so a validation cut short by the loan still leaves them.
for name in "${names[@]}"; do cp "$RUNS/$name/dancenet.pt" "$OUT/$name.pt" 2>/dev/null; done

# Each run (and the shipped weights, for the same run's reference) on the validation songs: foot model on,
# the shipped sampling settings, two takes; one process each, side by side on the machine's cores.
weights=(dancenet_core/weights/dancenet.pt)
for name in "${names[@]}"; do [[ -f "$RUNS/$name/dancenet.pt" ]] && weights+=("$RUNS/$name/dancenet.pt"); done
export OMP_NUM_THREADS=1 DANCENET_CACHE=$PWD/$RUNS/cache
for w in "${weights[@]}"; do
    v=$RUNS/validate/$(basename "$(dirname "$w")")
    mkdir -p "$v"
    dancenet validate "$w" --pack "$PACK" --temperatures 1.0 --smoothing 1.5 --takes 2 --out "$v" \
        >"$v.log" 2>&1 &
done
wait
# Logs and tables only: the weights are already in OUT, and their runtime twins (.npz) would push the archive past what
# a lent machine sends back.
tar czf "$OUT/sweep.tar.gz" --exclude='*.pt' --exclude='*.npz' --exclude=cache "$RUNS"
cat "$RUNS"/validate/*/validation.md 2>/dev/null | grep -E '^\|' | sort -u

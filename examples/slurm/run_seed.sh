#!/bin/bash
# One run of an ensemble: seed SEED (default: this SLURM array task's index) of preset PRESET
# into OUT/run_SSSS.h5 (docs/slurm.md). Rerun it and it resumes an interrupted run from its
# checkpoint (bit-identical to an uninterrupted one) or, for a finished run, does nothing.
#
#   PRESET=paper OUT=/scratch/runs/paper SEED=7 examples/slurm/run_seed.sh
#
# PRESET  smoke | default | paper | paper-fresh (required)
# OUT     the ensemble directory, on a file system every node sees (required)
# SEED    the seed (default: $SLURM_ARRAY_TASK_ID)
# SET     configuration keys "section.key=value ...", each passed as --set (optional)
# TILTPILE  the command (default: tiltpile; e.g. "/path/to/.venv/bin/tiltpile")
set -euo pipefail
: "${PRESET:?give PRESET (smoke, default, paper or paper-fresh)}"
: "${OUT:?give OUT, the ensemble directory}"
SEED=${SEED:-${SLURM_ARRAY_TASK_ID:-}}
: "${SEED:?give SEED, or run as a task of a SLURM array (sbatch --array)}"
TILTPILE=${TILTPILE:-tiltpile}

# one core per run; the kernels compiled once into a shared cache (ensemble.sbatch warms it)
export NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1
export NUMBA_CACHE_DIR=${NUMBA_CACHE_DIR:-$OUT/.numba-cache}

run=$(printf '%s/run_%04d.h5' "$OUT" "$SEED")
if [ -f "$run" ]; then
    echo "$run is finished"
    exit 0
fi
sets=()
for kv in ${SET:-}; do sets+=(--set "$kv"); done
mkdir -p "$OUT"
# prints the run's summary as one JSON line; a health stop or a bad value exits non-zero
$TILTPILE simulate --preset "$PRESET" ${sets[@]+"${sets[@]}"} --seed "$SEED" --out "$run" --quiet

#!/usr/bin/env bash
# A day of flights: compensate every log with the aircraft's model, check tracks, on all cores.
# Usage: cli/batch_example.sh LOG_FOLDER MODEL.json PLAN.csv OUT_FOLDER
set -euo pipefail
logs=${1:?log folder}; model=${2:?model json}; plan=${3:?plan csv}; out=${4:?output folder}

# All cores of this machine. A log is skipped when its outputs are newer than it and were made
# with the same options, model and plan contents and aeromag version (add --force to redo).
aeromag batch "$logs"/*.csv --model "$model" --plan "$plan" -o "$out" || status=$?

# Very large logs (1 kHz UAV): bounded memory, identical results.
#   aeromag batch "$logs" --model "$model" -o "$out" --chunk-rows 1000000
# Scale out: the same command on a Dask cluster (pip install 'aeromag[dask]').
#   dask scheduler & dask worker tcp://HOST:8786 --nworkers 8 &
#   aeromag batch "$logs" --model "$model" -o "$out" --scheduler tcp://HOST:8786

column -s, -t < "$out/batch_summary.csv" | cut -c1-160
exit "${status:-0}"

#!/usr/bin/env bash
# Calibrate on a calibration flight, then apply the model to every survey log of the day.
# Usage: cli/calibrate_then_compensate.sh CAL.csv OUTDIR SURVEY.csv [SURVEY.csv ...]
set -euo pipefail
cal=$1; out=$2; shift 2
mkdir -p "$out"
aeromag calibrate "$cal" -o "$out/aircraft.json"
for f in "$@"; do
  aeromag compensate "$f" --model "$out/aircraft.json" -o "$out/$(basename "${f%.*}")_comp.csv"
done

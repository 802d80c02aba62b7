#!/bin/sh
# Regenerate the shipped sample data (data_samples/) from the simulator; run from the repo root.
aeromag simulate -o data_samples --small --seed 1 --faults 0.1 --survey

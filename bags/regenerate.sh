#!/usr/bin/env bash
# Regenerate the shipped sample bags from the simulator (deterministic: fixed seeds).
# Run from the repository root with phid installed: bash bags/regenerate.sh
set -euo pipefail
cd "$(dirname "$0")/.."
rm -rf bags/catalogue bags/catalogue.truth.json bags/validation.mcap bags/validation.mcap.truth.json
rm -rf bags/saturation bags/saturation.truth.json
phid simulate --out bags/catalogue --seed 0
phid simulate --catalogue validation --out bags/validation.mcap --seed 1
phid simulate --out bags/saturation --seed 2 --duration 12 --effect magnetic_saturation=s10=0.07,s12=0.45

#!/usr/bin/env bash
# Regenerate the shipped sample bags from the simulator (deterministic: fixed seeds).
# Run from the repository root with phid installed: bash bags/regenerate.sh
set -euo pipefail
cd "$(dirname "$0")/.."
rm -rf bags/catalogue bags/catalogue.truth.json bags/validation.mcap bags/validation.mcap.truth.json
phid simulate --out bags/catalogue --seed 0
phid simulate --catalogue validation --out bags/validation.mcap --seed 1

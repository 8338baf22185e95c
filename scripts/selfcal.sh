#!/usr/bin/env bash
# The refinement from the images behind docs/guide/selfcal.md, into
# <reports>/selfcal/: fCal 2.0's calibration and validation sweeps compared with
# each other, from probecal's own calibration of the recording
# (reports/plus_fcal2_nwire, with its lag) and from PLUS's matrix (no lag), at
# selfcal's default settings, with the agreement profiled over the lag (±100 ms),
# and the turn the wires' straightness alone asks for (scripts/wire-lines.py).
# Skipped, saying so, when ../shared/data is absent.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
reports="${1:-reports}"
probecal="$CARGO_TARGET_DIR/debug/probecal"
fcal=../shared/data/plus-fcal2.0-3nwires
if [[ ! -d "$fcal" ]]; then
  echo "selfcal skipped: $fcal is absent" >&2
  exit 0
fi
sweeps=("$fcal/fCal_Test_Calibration_3NWires_fCal2.0.igs.mha" "$fcal/fCal_Test_Validation_3NWires_fCal2.0.igs.mha")
config="$fcal/PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml"
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
keep() { # the case's files, without the output guard's lock
  rm -rf "$reports/selfcal/$1"
  mkdir -p "$reports/selfcal/$1"
  find "$scratch/$1" -maxdepth 1 -type f ! -name '.*' -exec cp {} "$reports/selfcal/$1/" \;
}
"$probecal" selfcal "${sweeps[@]}" --config "$config" --calibration reports/plus_fcal2_nwire/fcal2_3nwires \
  --lag-range-ms 100 --out "$scratch/fcal2_from_probecal"
keep fcal2_from_probecal
"$probecal" selfcal "${sweeps[@]}" --config "$config" --calibration "$fcal/FreehandCalibration3NWires_fCal2.0.results.xml" \
  --lag-range-ms 100 --out "$scratch/fcal2_from_plus"
keep fcal2_from_plus
# The wires' straightness as a second objective, measured with numpy.
/usr/bin/python3 scripts/wire-lines.py "$reports"
echo "refinements written to $reports/selfcal/"

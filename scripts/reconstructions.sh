#!/usr/bin/env bash
# The reconstructions behind docs/results/reconstruction.md, into <reports>/reconstruction/:
# PLUS's three volume-reconstruction regression cases, each compared with PLUS's
# own volume (agreement.json), and the fCal 2.0 N-wire validation sweep placed with
# probecal's calibration of the fCal recording (reports/plus_fcal2_nwire, as the
# main job writes it and the repository keeps it) and with PLUS's, each with its
# wires measured. Times are left out so that the files regenerate
# byte-identical; the volumes themselves are not kept (they are large and
# regenerate from the shared data). Skipped, saying so, when ../shared/data is absent.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
reports="${1:-reports}"
probecal="$CARGO_TARGET_DIR/debug/probecal"
data=../shared/data/plus-volume-reconstruction
fcal=../shared/data/plus-fcal2.0-3nwires
if [[ ! -d "$data" || ! -d "$fcal" ]]; then
  echo "reconstructions skipped: $data or $fcal is absent" >&2
  exit 0
fi
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
keep() { # the case's folder without its volumes
  rm -rf "$reports/reconstruction/$1"
  mkdir -p "$reports/reconstruction/$1"
  find "$scratch/$1" -maxdepth 1 -type f ! -name 'volume.*' ! -name '.*' -exec cp {} "$reports/reconstruction/$1/" \;
}
for case in SpinePhantom_NN_MEAN:NNMEAN SpinePhantom_LN_MAXI:LNMAXI SonixRP_TRUS_D70mm_LN_MEAN:LNMEAN; do
  name="${case%%:*}"
  reference="$data/vtkVolumeReconstructorTest${case##*:}volumeRef.mha"
  "$probecal" reconstruct "$data/SpinePhantomFreehand.igs.mha" \
    --config "$data/PlusDeviceSet_VolumeReconstructionOnly_$name.xml" \
    --compare "$reference" --no-times --out "$scratch/$name" >/dev/null
  keep "$name"
done
"$probecal" reconstruct "$fcal/fCal_Test_Validation_3NWires_fCal2.0.igs.mha" \
  --config experiments/plus/fcal2_volume.xml --wires "$fcal/PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml" \
  --calibration reports/plus_fcal2_nwire/fcal2_3nwires --no-times --out "$scratch/fcal2_validation" >/dev/null
keep fcal2_validation
# The same sweep placed with PLUS's own ImageToProbe: its wires beside ours.
"$probecal" reconstruct "$fcal/fCal_Test_Validation_3NWires_fCal2.0.igs.mha" \
  --config experiments/plus/fcal2_volume.xml --wires "$fcal/PlusDeviceSet_fCal_Sim_SpatialCalibration_2.0.xml" \
  --calibration "$fcal/FreehandCalibration3NWires_fCal2.0.results.xml" --no-times \
  --out "$scratch/fcal2_validation_plus_matrix" >/dev/null
keep fcal2_validation_plus_matrix
echo "reconstructions written to $reports/reconstruction/"

#!/usr/bin/env bash
# Writes reports/study/paired/: one estimator against another on the same
# seeds (`probecal study compare A B --method M --method-b N`), the comparisons
# the docs' method-against-method claims quote. Expects a built binary.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
probecal="$CARGO_TARGET_DIR/debug/probecal"
s=reports/study
pair() { # name, study A, method of A, study B, method of B
  "$probecal" study compare "$2" "$4" --method "$3" --method-b "$5" --out "$s/paired/$1.json" >/dev/null
}
mkdir -p "$s/paired"
pair hemisphere_lmeds_vs_reported $s/study.json cutoff_worst_first $s/study.json lmeds
pair hemisphere_lmeds_vs_thesis $s/study.json thesis_one_shot $s/study.json lmeds
pair off_centre_lmeds_vs_thesis $s/off_centre_planes/study.json thesis_one_shot $s/off_centre_planes/study.json lmeds
pair more_outliers_lmeds_vs_thesis $s/more_outliers/study.json thesis_one_shot $s/more_outliers/study.json lmeds
pair spheres_plain_vs_pose_prior $s/spheres/study.json sphere_fit_pose_prior $s/spheres/study.json sphere_fit
pair spheres_centres_vs_pose_prior $s/spheres/study.json sphere_fit_pose_prior $s/spheres/study.json cutoff_worst_first
pair spheres_pose_prior_vs_hemisphere_thesis $s/study.json thesis_one_shot $s/spheres/study.json sphere_fit_pose_prior
pair spheres_pose_prior_vs_hemisphere_reported $s/study.json cutoff_worst_first $s/spheres/study.json sphere_fit_pose_prior
pair twin_spheres_pose_prior_vs_plain_design $s/thesis_twin_spheres_choice/chosen/study.json sphere_fit $s/thesis_twin_spheres_choice/chosen/study.json sphere_fit_pose_prior
pair twin_spheres_pose_prior_vs_plain $s/thesis_twin_spheres/study.json sphere_fit $s/thesis_twin_spheres/study.json sphere_fit_pose_prior
pair twin_spheres_centres_vs_plain $s/thesis_twin_spheres/study.json sphere_fit $s/thesis_twin_spheres/study.json cutoff_worst_first
pair twin_domes_vs_thesis $s/thesis_twin_dataset3/study.json thesis_one_shot $s/thesis_twin_spheres/study.json sphere_fit
pair twin_domes_vs_pixel_fit $s/thesis_twin_dataset3/study.json ransac_lm_scales $s/thesis_twin_spheres/study.json sphere_fit
pair twin_pixel_fit_vs_thesis $s/thesis_twin_dataset3/study.json thesis_one_shot $s/thesis_twin_dataset3/study.json ransac_lm_scales
pair twin_aruco_pixel_fit_vs_thesis $s/thesis_twin_aruco/study.json thesis_one_shot $s/thesis_twin_aruco/study.json ransac_lm_scales
echo "$(ls "$s"/paired/*.json | wc -l) comparisons in $s/paired"

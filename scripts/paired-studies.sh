#!/usr/bin/env bash
# Writes every committed paired comparison of studies from the study files
# they pair: reports/study/paired/ (one estimator against another on the same
# seeds, `probecal study compare A B --method M --method-b N`) and the
# `<name>_vs_<name>.json` of the study folders (one study against another,
# every method they share). The docs' comparison claims quote these. Expects a
# built binary.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/env.sh
probecal="$CARGO_TARGET_DIR/debug/probecal"
s=reports/study
pair() { # name, study A, method of A, study B, method of B
  "$probecal" study compare "$2" "$4" --method "$3" --method-b "$5" --out "$s/paired/$1.json" --force >/dev/null
}
studies() { # name under reports/study, study A, study B
  "$probecal" study compare "$2" "$3" --out "$s/$1.json" --force >/dev/null
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
# The ideal lab against the thesis's twin (realism at physical values), each
# method against itself on the seeds both ran: the README's side-by-side.
pair ideal_vs_twin_hemisphere $s/study.json cutoff_worst_first $s/thesis_twin_dataset3/study.json cutoff_worst_first
pair ideal_vs_twin_spheres $s/spheres/study.json sphere_fit $s/thesis_twin_spheres/study.json sphere_fit
pair ideal_vs_twin_spheres_pose_prior $s/spheres/study.json sphere_fit_pose_prior $s/thesis_twin_spheres/study.json sphere_fit_pose_prior
studies error_budget/more_outliers_vs_default $s/study.json $s/more_outliers/study.json
studies error_budget/off_centre_planes_vs_default $s/study.json $s/off_centre_planes/study.json
studies error_budget/planes_through_centre_vs_default $s/study.json $s/planes_through_centre/study.json
studies error_budget/true_camera_vs_default $s/study.json $s/true_camera/study.json
studies rigs/charuco_occluded_vs_clear $s/rigs/charuco/study.json $s/rigs/charuco_occluded/study.json
studies rigs/charuco_vs_aruco $s/rigs/aruco/study.json $s/rigs/charuco/study.json
studies rigs/charuco_vs_checkerboard $s/study.json $s/rigs/charuco/study.json
studies rigs/checkerboard_occluded_vs_clear $s/study.json $s/rigs/checkerboard_occluded/study.json
studies rigs/occluded_charuco_vs_checkerboard $s/rigs/checkerboard_occluded/study.json $s/rigs/charuco_occluded/study.json
studies spheres_edge/obliquity_vs_none $s/spheres_uniform_arcs/study.json $s/spheres_edge/obliquity/study.json
studies spheres_edge/slice_offset_vs_slice_weights $s/spheres_design_seeds/study.json $s/spheres_edge/slice/study.json
studies spheres_edge/slice_vs_none $s/spheres_uniform_arcs/study.json $s/spheres_edge/slice/study.json
studies spheres_heldout/design_uniform_arcs_vs_chosen $s/spheres_design_seeds/study.json $s/spheres_uniform_arcs/study.json
studies spheres_heldout/design_views_only_vs_chosen $s/spheres_choice/refine/study.json $s/spheres_choice/views_only/study.json
studies spheres_heldout/edge_slice_vs_chosen $s/spheres/study.json $s/spheres_heldout/edge_slice/study.json
studies spheres_heldout/uniform_arcs_vs_chosen $s/spheres/study.json $s/spheres_heldout/uniform_arcs/study.json
studies spheres_heldout/views_only_vs_chosen $s/spheres/study.json $s/spheres_views_only/study.json
studies spheres_normal_peak_vs_column_peak $s/spheres_design_seeds/study.json $s/spheres_normal_peak/study.json
studies spheres_prior/blur_double_vs_stated $s/spheres/study.json $s/spheres_prior/blur_double/study.json
studies spheres_prior/blur_half_vs_stated $s/spheres/study.json $s/spheres_prior/blur_half/study.json
studies spheres_prior/prior_double_vs_stated $s/spheres/study.json $s/spheres_prior/prior_double/study.json
studies spheres_prior/prior_half_vs_stated $s/spheres/study.json $s/spheres_prior/prior_half/study.json
studies thesis_twin_spheres_heldout/design_nominal_pixels_vs_chosen $s/thesis_twin_spheres_choice/chosen/study.json $s/thesis_twin_spheres_choice/nominal_pixels/study.json
studies thesis_twin_spheres_heldout/design_refine_vs_chosen $s/thesis_twin_spheres_choice/chosen/study.json $s/thesis_twin_spheres_choice/refine/study.json
studies thesis_twin_spheres_heldout/nominal_pixels_vs_chosen $s/thesis_twin_spheres/study.json $s/thesis_twin_spheres_heldout/nominal_pixels/study.json
studies thesis_twin_spheres_heldout/refine_vs_chosen $s/thesis_twin_spheres/study.json $s/thesis_twin_spheres_heldout/refine/study.json
echo "$(find "$s" -name '*_vs_*.json' | wc -l) comparisons in $s"

//! `probecal design`: the dome-phantom layouts of the manifest's lab ranked by
//! the Cramér–Rao bound of their calibration (`design.json`, `design.md`).

use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;

use crate::estimate::edge_blur::SliceBlur;
use crate::estimate::edge_offset::EdgeOffset;
use crate::pipeline::run::design::{self, Bound, BoundError, BoundNoise, DesignRow, DESIGN_SEEDS};
use crate::report::error::OutputError;
use crate::spec::phantom::Phantom;

#[derive(Serialize)]
struct DesignFile<'a> {
    experiment: &'a str,
    seeds: [u64; 2],
    frames: usize,
    noise: BoundNoise,
    /// The intrinsics also solved from the boards in the frames' photos.
    camera_refined_with_frames: bool,
    /// The terms of the echo edge's offset solved with the calibration
    /// (nuisances of the bound; absent: none).
    #[serde(skip_serializing_if = "is_no_offset")]
    edge_offset: EdgeOffset,
    /// The growth of the edge noise with the cut (absent: every arc alike).
    #[serde(skip_serializing_if = "Option::is_none")]
    slice_blur: Option<SliceBlur>,
    /// The manifest's own phantom.
    #[serde(serialize_with = "design::bound_or_reason")]
    manifest_phantom: Result<Bound, BoundError>,
    /// The thesis's hemisphere (R = 15 mm) at the lab's feature point.
    #[serde(serialize_with = "design::bound_or_reason")]
    hemisphere: Result<Bound, BoundError>,
    layouts: &'a [DesignRow],
}

fn is_no_offset(o: &EdgeOffset) -> bool {
    *o == EdgeOffset::None
}

fn bound_cell(b: &Result<Bound, BoundError>) -> String {
    match b {
        Ok(b) => format!("{:.3}", b.rms_mm),
        Err(e) => format!("— ({e})"),
    }
}

fn markdown(file: &DesignFile<'_>) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Dome layouts ranked by the Cramér–Rao bound ({}, the sweeps of seeds {} to {}, {} frames each)\n",
        file.experiment, file.seeds[0], file.seeds[1], file.frames
    );
    let n = &file.noise;
    let _ = writeln!(
        s,
        "Bound: RMS error over the image's corners and centre (mm) of any unbiased estimate from the arcs' edges \
         (RMS over the sweeps), \
         with edge noise {} mm (an arc worth {} points{}); each frame's `phantom_T_marker` from the photo's \
         board poses, with corner noise {} px (probe board) and {} px (phantom board) and the sweep's tremor \
         between photo and B-scan, and the camera's intrinsics known only as well as its calibration views \
         (corner noise {} px){} pin them down, one error shared by every frame{}.\n",
        n.edge_sd_mm,
        n.points_per_arc,
        match file.slice_blur {
            None => String::new(),
            Some(b) => format!(
                "; its variance grown by 1 + (σ_e·|d|/(r·σ_a))² for an arc cut d from its dome's centre, \
                 pulse σ_a {} mm and slice σ_e {} mm: `solve.sphere_fit.pose_prior.slice_blur`, as the fit weighs it",
                b.axial_sd_mm, b.elevation_sd_mm
            ),
        },
        n.probe_corner_sd_px,
        n.phantom_corner_sd_px,
        n.calibration_corner_sd_px,
        if file.camera_refined_with_frames {
            " and every frame's two boards, a board where an earlier photo saw it counted once \
             (`camera.calibrate.refine_with_frames`),"
        } else {
            ""
        },
        match file.edge_offset {
            EdgeOffset::None => String::new(),
            model => format!(
                "; the echo edge's offset outside its sphere unknown too (`{}`: the terms of a + b·(d/R)² the fit \
                 solves, without a prior)",
                model.name()
            ),
        }
    );
    let _ = writeln!(
        s,
        "The manifest's phantom: {} mm. The thesis's hemisphere (R = 15 mm) at the same place: {} mm.\n",
        bound_cell(&file.manifest_phantom),
        bound_cell(&file.hemisphere)
    );
    let _ = writeln!(
        s,
        "| rank | domes | R (mm) | gap (mm) | stagger (mm) | height step (mm) | bound (mm) | frames | arcs |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    for (i, row) in file.layouts.iter().enumerate() {
        let l = &row.layout;
        let (frames, arcs) = match &row.bound {
            Ok(b) => (b.frames.to_string(), b.arcs.to_string()),
            Err(_) => ("—".into(), "—".into()),
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {frames} | {arcs} |",
            i + 1,
            l.domes,
            l.radius_mm,
            l.gap_mm,
            l.stagger_mm,
            l.height_step_mm,
            bound_cell(&row.bound)
        );
    }
    if let Some(best) = file.layouts.first() {
        let _ = writeln!(s, "\nThe best layout's domes (phantom frame, mm):\n");
        if let Phantom::Spheres { spheres } = &best.phantom {
            for sphere in spheres {
                let c = sphere.centre_in_phantom_mm;
                let _ = writeln!(
                    s,
                    "- {{name: {}, centre_in_phantom_mm: [{}, {}, {}], radius_mm: {}}}",
                    sphere.name, c[0], c[1], c[2], sphere.radius_mm
                );
            }
        }
    }
    s
}

/// Writes `design.json` and `design.md` into `out` for the ranked `rows` (with
/// the manifest's own phantom and the thesis's hemisphere beside them); the
/// Markdown page.
pub fn write(
    manifest: &crate::manifest::Manifest,
    spec: &crate::spec::render::RenderSpec,
    rows: &[DesignRow],
    out: &Path,
) -> Result<String, OutputError> {
    let hemisphere = match crate::detect::board_pose::RigBoards::from_rig(&manifest.rig) {
        Ok(rig) => {
            let (_, world_T_phantom) = crate::synth::scene::lab_layout(spec.board_distance_mm, &rig.phantom);
            let c = world_T_phantom.inverse() * nalgebra::Point3::origin();
            design::bound_over_sweeps(
                manifest,
                &Phantom::Hemisphere {
                    centre_in_phantom_mm: [c.x, c.y, c.z],
                    radius_mm: 15.0,
                },
                spec,
                DESIGN_SEEDS,
            )
        }
        Err(e) => Err(BoundError::Scene(e.to_string())),
    };
    let file = DesignFile {
        experiment: &manifest.experiment,
        seeds: [DESIGN_SEEDS.start, DESIGN_SEEDS.end - 1],
        frames: spec.frames,
        noise: design::noise(manifest),
        camera_refined_with_frames: design::refines_with_frames(manifest),
        edge_offset: design::edge_offset_model(manifest),
        slice_blur: design::slice_blur_model(manifest),
        manifest_phantom: design::bound_over_sweeps(manifest, &manifest.phantom, spec, DESIGN_SEEDS),
        hemisphere,
        layouts: rows,
    };
    let json = crate::io::json::to_text(&file)?;
    let md = markdown(&file);
    crate::io::fs::write_all_atomic(
        out,
        &[
            ("design.json".into(), json.into_bytes()),
            ("design.md".into(), md.clone().into_bytes()),
        ],
    )?;
    Ok(md)
}

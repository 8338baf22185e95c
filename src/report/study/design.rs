//! `probecal design`: the dome-phantom layouts of the manifest's lab ranked by
//! the Cramér–Rao bound of their calibration (`design.json`, `design.md`).

use std::fmt::Write as _;
use std::path::Path;

use crate::estimate::edge_offset::EdgeOffset;
use crate::pipeline::run::design::{Bound, BoundError, DesignStudy};
use crate::report::error::OutputError;
use crate::spec::phantom::Phantom;

fn bound_cell(b: &Result<Bound, BoundError>) -> String {
    match b {
        Ok(b) => format!("{:.3}", b.rms_mm),
        Err(e) => format!("— ({e})"),
    }
}

fn markdown(file: &DesignStudy) -> String {
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

/// Writes `design.json` and `design.md` into `out`; the Markdown page.
pub fn write(file: &DesignStudy, out: &Path) -> Result<String, OutputError> {
    let json = crate::io::json::to_text(file)?;
    let md = markdown(file);
    crate::io::fs::write_all_atomic(
        out,
        &[
            ("design.json".into(), json.into_bytes()),
            ("design.md".into(), md.clone().into_bytes()),
        ],
    )?;
    Ok(md)
}

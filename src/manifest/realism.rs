//! Checks of a rendered dataset's error sources (`render.realism`): every value
//! finite and in its physical range, named by its field.

use super::checker::Checker;
use crate::spec::realism::Realism;

/// Speeds of sound a medium can have (air to bone), m/s.
const SPEED_OF_SOUND_M_PER_S: (f64, f64) = (300.0, 5000.0);

pub(crate) fn check(c: &mut Checker<'_>, field: &str, r: &Realism) {
    if let Some(s) = &r.speed_of_sound {
        let (lo, hi) = SPEED_OF_SOUND_M_PER_S;
        for (name, v) in [
            ("scanner_m_per_s", s.scanner_m_per_s),
            ("medium_m_per_s", s.medium_m_per_s),
        ] {
            if !(lo..=hi).contains(&v) {
                c.fail(
                    &format!("{field}.speed_of_sound.{name}"),
                    format!("must be a speed of sound between {lo} and {hi} m/s, got {v}"),
                );
            }
        }
    }
    if let Some(m) = &r.phantom_measurement {
        c.at_least(
            &format!("{field}.phantom_measurement.position_sd_mm"),
            m.position_sd_mm,
            0.0,
        );
        c.at_least(
            &format!("{field}.phantom_measurement.radius_sd_mm"),
            m.radius_sd_mm,
            0.0,
        );
    }
    if let Some(b) = &r.board_print {
        if !(0.0..=0.1).contains(&b.scale_sd) {
            c.fail(
                &format!("{field}.board_print.scale_sd"),
                format!("must be between 0 and 0.1 (10 %), got {}", b.scale_sd),
            );
        }
    }
    if let Some(w) = &r.board_warp {
        c.at_least(&format!("{field}.board_warp.bow_sd_mm"), w.bow_sd_mm, 0.0);
    }
    if let Some(m) = &r.marker_mount {
        c.at_least(&format!("{field}.marker_mount.position_sd_mm"), m.position_sd_mm, 0.0);
        c.at_least(&format!("{field}.marker_mount.rotation_sd_deg"), m.rotation_sd_deg, 0.0);
    }
    if let Some(s) = &r.shutter {
        c.at_least(&format!("{field}.shutter.asynchrony_sd_s"), s.asynchrony_sd_s, 0.0);
    }
    if let Some(m) = &r.motion_blur {
        if !(0.0..=1.0).contains(&m.exposure_s) {
            c.fail(
                &format!("{field}.motion_blur.exposure_s"),
                format!("must be between 0 and 1 s, got {}", m.exposure_s),
            );
        }
    }
    if let Some(j) = &r.jpeg {
        if !(1..=100).contains(&j.quality) {
            c.fail(
                &format!("{field}.jpeg.quality"),
                format!("must be between 1 and 100, got {}", j.quality),
            );
        }
    }
    if let Some(l) = &r.lens {
        c.finite(&format!("{field}.lens.distortion"), &l.distortion);
        if l.calibration_views < 4 {
            c.fail(
                &format!("{field}.lens.calibration_views"),
                format!("camera calibration needs at least 4 views, got {}", l.calibration_views),
            );
        }
    }
    if let Some(b) = &r.beam_width {
        c.at_least(
            &format!("{field}.beam_width.slice_thickness_mm"),
            b.slice_thickness_mm,
            0.0,
        );
    }
    if let Some(h) = &r.hand {
        c.at_least(&format!("{field}.hand.speed_mm_per_s"), h.speed_mm_per_s, 0.0);
        c.at_least(&format!("{field}.hand.rotation_deg_per_s"), h.rotation_deg_per_s, 0.0);
    }
    let moving = r.shutter.is_some() || r.motion_blur.is_some();
    if moving && r.hand.is_none() {
        c.fail(
            &format!("{field}.hand"),
            "the shutter's asynchrony and motion blur need the hand's speed (hand.speed_mm_per_s, hand.rotation_deg_per_s)",
        );
    }
}

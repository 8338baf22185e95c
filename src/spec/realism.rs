//! The error sources of a real rig that a rendered dataset can carry on top of
//! the ideal lab (`render.realism` in a manifest). Each is a physical quantity
//! with a stated distribution; the manifest that sets it says where its value
//! comes from. A source that is absent is not there at all (the ideal rig), so an
//! ablation switches a source off by leaving it out.
//!
//! Draws: systematic sources (the phantom's measured centre, the boards' print
//! scale) are drawn once per rendered dataset from the seed's own stream;
//! per-frame sources (mount, shutter, motion) once per frame from the frame's.

use serde::{Deserialize, Serialize};

/// The error sources; every field absent means the ideal rig.
#[derive(Debug, Clone, PartialEq, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Realism {
    /// The scanner converts echo time to depth with its assumed speed of sound.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_of_sound: Option<SpeedOfSound>,
    /// The phantom's features were measured by hand from the phantom board; the
    /// print has a size tolerance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub phantom_measurement: Option<PhantomMeasurement>,
    /// The printed boards' scale differs from the nominal square size.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub board_print: Option<BoardPrint>,
    /// The boards are not flat: each bows along its width.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub board_warp: Option<BoardWarp>,
    /// The probe board is not perfectly rigid to the probe (clip, glue, casing).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub marker_mount: Option<MarkerMount>,
    /// The photo and the B-scan are taken at slightly different moments while the
    /// hand moves the probe.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shutter: Option<Shutter>,
    /// The probe moves during the photo's exposure.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion_blur: Option<MotionBlur>,
    /// The camera saves its photos as JPEG.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jpeg: Option<Jpeg>,
    /// The camera's lens and its calibration set: replaces the ideal camera's
    /// distortion and number of calibration views.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lens: Option<Lens>,
    /// The beam's elevation (out-of-plane) thickness: replaces the ideal probe's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beam_width: Option<BeamWidth>,
    /// The hand that holds the probe: how fast it moves (used by `shutter` and
    /// `motion_blur`; not an error source by itself).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hand: Option<Hand>,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SpeedOfSound {
    /// What the scanner assumes (tissue), m/s.
    pub scanner_m_per_s: f64,
    /// What the sound travels at in the phantom's medium, m/s.
    pub medium_m_per_s: f64,
}

impl SpeedOfSound {
    /// True range per displayed range: an echo displayed at depth `d` is at `d` times this.
    pub fn range_scale(&self) -> f64 {
        self.medium_m_per_s / self.scanner_m_per_s
    }
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PhantomMeasurement {
    /// SD of each coordinate of a feature's measured position, mm.
    pub position_sd_mm: f64,
    /// SD of a printed sphere's radius about its nominal value, mm.
    #[serde(default)]
    pub radius_sd_mm: f64,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BoardPrint {
    /// SD of each printed board's scale about 1 (e.g. 0.003 = 0.3 %).
    pub scale_sd: f64,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BoardWarp {
    /// SD of each board's bow (the sagitta over its width), mm.
    pub bow_sd_mm: f64,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MarkerMount {
    /// SD of the board's shift against the probe, per axis and frame, mm.
    pub position_sd_mm: f64,
    /// SD of its rotation about each axis, per frame, degrees.
    pub rotation_sd_deg: f64,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Shutter {
    /// SD of the time between the B-scan and the photo, s.
    pub asynchrony_sd_s: f64,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MotionBlur {
    /// The photo's exposure time, s.
    pub exposure_s: f64,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Jpeg {
    /// JPEG quality, 1..=100.
    pub quality: u8,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Lens {
    /// OpenCV order: k1, k2, p1, p2, k3.
    pub distortion: [f64; 5],
    /// Views of the calibration board taken to calibrate the camera.
    pub calibration_views: usize,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BeamWidth {
    /// Elevation thickness of the beam over the phantom's depths, mm.
    pub slice_thickness_mm: f64,
}

#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Hand {
    /// RMS speed of the probe marker's origin, mm/s.
    pub speed_mm_per_s: f64,
    /// RMS angular speed of the probe, degrees/s.
    pub rotation_deg_per_s: f64,
}

/// The names of the error sources, in manifest order (what an ablation toggles).
pub const SOURCES: [&str; 10] = [
    "speed_of_sound",
    "phantom_measurement",
    "board_print",
    "board_warp",
    "marker_mount",
    "shutter",
    "motion_blur",
    "jpeg",
    "lens",
    "beam_width",
];

impl Realism {
    /// Whether the named source is present.
    pub fn has(&self, source: &str) -> bool {
        match source {
            "speed_of_sound" => self.speed_of_sound.is_some(),
            "phantom_measurement" => self.phantom_measurement.is_some(),
            "board_print" => self.board_print.is_some(),
            "board_warp" => self.board_warp.is_some(),
            "marker_mount" => self.marker_mount.is_some(),
            "shutter" => self.shutter.is_some(),
            "motion_blur" => self.motion_blur.is_some(),
            "jpeg" => self.jpeg.is_some(),
            "lens" => self.lens.is_some(),
            "beam_width" => self.beam_width.is_some(),
            _ => false,
        }
    }

    /// This rig with the named source left out.
    pub fn without(&self, source: &str) -> Realism {
        let mut r = self.clone();
        match source {
            "speed_of_sound" => r.speed_of_sound = None,
            "phantom_measurement" => r.phantom_measurement = None,
            "board_print" => r.board_print = None,
            "board_warp" => r.board_warp = None,
            "marker_mount" => r.marker_mount = None,
            "shutter" => r.shutter = None,
            "motion_blur" => r.motion_blur = None,
            "jpeg" => r.jpeg = None,
            "lens" => r.lens = None,
            "beam_width" => r.beam_width = None,
            _ => {}
        }
        r
    }

    /// The ideal rig with only the named source of this one (and the hand).
    pub fn only(&self, source: &str) -> Realism {
        SOURCES
            .into_iter()
            .filter(|s| *s != source)
            .fold(self.clone(), |r, s| r.without(s))
    }

    /// The present sources, in manifest order.
    pub fn present(&self) -> Vec<&'static str> {
        SOURCES.into_iter().filter(|s| self.has(s)).collect()
    }
}

//! The probe's convex array and the B-scan raster: where an image point is in
//! the fan, and where the scanner displays it.

/// The probe's convex array and the B-scan raster.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BscanGeometry {
    pub width_px: usize,
    pub height_px: usize,
    pub spacing_mm_per_px: [f64; 2],
    /// Virtual apex of the fan in the image frame, mm.
    pub apex_mm: [f64; 2],
    pub convex_radius_mm: f64,
    pub depth_mm: f64,
    pub half_fan_rad: f64,
}

impl BscanGeometry {
    pub fn new(spacing_mm_per_px: [f64; 2], depth_mm: f64, fan_deg: f64, convex_radius_mm: f64) -> Self {
        let half_fan_rad = (fan_deg / 2.0).to_radians();
        let width_mm = 2.0 * (convex_radius_mm + depth_mm) * half_fan_rad.sin();
        BscanGeometry {
            width_px: (width_mm / spacing_mm_per_px[0]).ceil() as usize + 1,
            height_px: (depth_mm / spacing_mm_per_px[1]).ceil() as usize + 1,
            spacing_mm_per_px,
            apex_mm: [width_mm / 2.0, -convex_radius_mm],
            convex_radius_mm,
            depth_mm,
            half_fan_rad,
        }
    }

    pub fn width_mm(&self) -> f64 {
        2.0 * self.apex_mm[0]
    }

    /// Polar coordinates (radius from the apex, angle from the central beam) of an image point, mm.
    pub fn polar(&self, u_mm: f64, v_mm: f64) -> (f64, f64) {
        let dx = u_mm - self.apex_mm[0];
        let dy = v_mm - self.apex_mm[1];
        ((dx * dx + dy * dy).sqrt(), dx.atan2(dy))
    }

    /// Where a point of the image plane (true mm) is displayed when echo ranges
    /// are scaled by `1 / range_scale` (the speed of sound's mismatch).
    pub fn displayed(&self, u_mm: f64, v_mm: f64, range_scale: f64) -> (f64, f64) {
        if range_scale == 1.0 {
            return (u_mm, v_mm);
        }
        let (r, angle) = self.polar(u_mm, v_mm);
        let shown = self.convex_radius_mm + (r - self.convex_radius_mm) / range_scale;
        (
            self.apex_mm[0] + shown * angle.sin(),
            self.apex_mm[1] + shown * angle.cos(),
        )
    }

    pub fn inside_fan(&self, u_mm: f64, v_mm: f64) -> bool {
        let (r, angle) = self.polar(u_mm, v_mm);
        angle.abs() <= self.half_fan_rad && r >= self.convex_radius_mm && r <= self.convex_radius_mm + self.depth_mm
    }
}

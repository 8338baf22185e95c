//! A device set's `<VolumeReconstruction>` element: PLUS's volume-reconstruction
//! settings, each with the meaning and units of PLUS's documentation
//! (`docs/algorithms/AlgorithmVolumeReconstruction.md` in PlusToolkit/PlusLib).
//!
//! Every value is checked where it is read; an error names the file, the line of
//! the element and the attribute. Settings PLUS documents but probecal does not
//! implement (`EnableFanAnglesAutoDetect="TRUE"`) are refused, never ignored.

use std::path::{Path, PathBuf};

use super::config::{parse_xml, read_text, ConfigError, Xml};

/// How an input pixel is spread into the volume.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Interpolation {
    /// Into the nearest voxel.
    NearestNeighbor,
    /// Into the 8 surrounding voxels with trilinear weights.
    Linear,
}

/// How values that meet in one voxel combine.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Compounding {
    Mean,
    Latest,
    Maximum,
}

/// PLUS's `Optimization`: `Full` computes voxel positions in 14-bit fixed point
/// (PLUS's integer math), the others in double precision.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Optimization {
    None,
    Partial,
    Full,
}

/// The fan that clips each image (pixels, degrees), applied inside the clip rectangle.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Fan {
    /// `FanAnglesDeg`: the edges' angles from the image's downward column axis.
    pub angles_deg: [f64; 2],
    /// `FanOriginPixel`.
    pub origin_px: [f64; 2],
    /// `FanRadiusStartPixel`, `FanRadiusStopPixel`.
    pub radius_start_px: f64,
    pub radius_stop_px: f64,
}

/// One `<HoleFillingElement>`: tried in order until one fills the hole.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum HoleFilling {
    /// Interpolation along the shortest of 13 sticks through the hole.
    Stick { length_limit: usize, sticks_to_use: usize },
    /// Gaussian-weighted mean of the known voxels of a `size`³ cube.
    Gaussian {
        size: usize,
        stdev: f64,
        min_known_ratio: f64,
    },
    /// As `Gaussian`, each voxel weighted by its accumulated weight too.
    GaussianAccumulation {
        size: usize,
        stdev: f64,
        min_known_ratio: f64,
    },
    /// Mean of the known voxels of the smallest cube (3³, 5³, … `size`³) that has any.
    NearestNeighbor { size: usize, min_known_ratio: f64 },
    /// Inverse-distance-weighted mean of the known voxels of a `size`³ cube.
    DistanceWeightInverse { size: usize, min_known_ratio: f64 },
}

/// `<VolumeReconstruction>`, checked.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VolumeSettings {
    pub path: PathBuf,
    /// Line of the element.
    pub line: usize,
    /// `ImageCoordinateFrame`, `ReferenceCoordinateFrame` (PLUS's `Image`, `Reference` when absent).
    pub image_frame: String,
    pub reference_frame: String,
    /// `OutputSpacing` (mm), required.
    pub spacing_mm: [f64; 3],
    /// `OutputOrigin` (mm) and `OutputExtent` (voxel index ranges, inclusive), or
    /// neither: then both are found from the clipped frames.
    pub origin_mm: Option<[f64; 3]>,
    pub extent: Option<[i64; 6]>,
    /// `ClipRectangleOrigin`, `ClipRectangleSize` (px; size 0 0: the whole frame).
    pub clip_origin_px: [usize; 2],
    pub clip_size_px: [usize; 2],
    /// Fan clipping, where `FanAnglesDeg` is not `0 0`.
    pub fan: Option<Fan>,
    /// `PixelRejectionThreshold`: pixels darker than it are not inserted.
    pub pixel_rejection_threshold: Option<f64>,
    /// `SkipInterval`: every n-th frame is used (1: all).
    pub skip_interval: usize,
    pub interpolation: Interpolation,
    pub compounding: Compounding,
    pub optimization: Optimization,
    /// `NumberOfThreads` (0: all cores). The volume is the same whatever the count.
    pub threads: usize,
    /// `FillHoles="ON"`: the elements of `<HoleFilling>` in order.
    pub hole_filling: Vec<HoleFilling>,
    /// `ImportanceMaskFilename`: a frame-sized 8-bit image whose values (0–255)
    /// weight each pixel's contribution (0: not inserted), resolved against the
    /// configuration's folder.
    pub importance_mask: Option<PathBuf>,
}

/// The largest output spacing, clip size and stick length accepted (a typo, not a volume).
const MAX_SPACING_MM: f64 = 100.0;
/// The smallest output spacing accepted: a micrometre, far below any
/// ultrasound's resolution (a smaller one is a typo, and at 1e-300 mm the grid's
/// arithmetic leaves the numbers).
const MIN_SPACING_MM: f64 = 0.001;
const MAX_KERNEL: usize = 99;

impl VolumeSettings {
    /// Reads the `<VolumeReconstruction>` element of a device set.
    pub fn read(path: &Path) -> Result<VolumeSettings, ConfigError> {
        VolumeSettings::parse(path, &read_text(path)?)
    }

    /// The files a device set at `path` names for the reconstruction (its
    /// importance mask), for the output guard: none where it cannot be read
    /// (reading it later says why).
    pub fn named_files(path: &Path) -> Vec<PathBuf> {
        VolumeSettings::read(path)
            .ok()
            .and_then(|s| s.importance_mask)
            .into_iter()
            .collect()
    }

    pub fn parse(path: &Path, text: &str) -> Result<VolumeSettings, ConfigError> {
        let doc = parse_xml(path, text)?;
        let x = Xml { path, doc: &doc };
        let mut found = doc.descendants().filter(|n| n.has_tag_name("VolumeReconstruction"));
        let node = found.next().ok_or_else(|| ConfigError {
            path: path.to_path_buf(),
            line: None,
            message: "no <VolumeReconstruction> element: the device set has no reconstruction settings".into(),
        })?;
        if let Some(second) = found.next() {
            return Err(x.fail(
                second,
                format!(
                    "a second <VolumeReconstruction> element (the first is on line {}): which one is meant?",
                    x.line(node)
                ),
            ));
        }
        let r = Reader { x: &x, node };
        let spacing = r.positive_triple("OutputSpacing")?.ok_or_else(|| {
            x.fail(
                node,
                "<VolumeReconstruction> needs `OutputSpacing` (mm per voxel, 3 numbers)".into(),
            )
        })?;
        let (origin_mm, extent) = r.origin_and_extent()?;
        let (clip_origin_px, clip_size_px) = r.clip_rectangle()?;
        Ok(VolumeSettings {
            path: path.to_path_buf(),
            line: x.line(node),
            image_frame: node.attribute("ImageCoordinateFrame").unwrap_or("Image").to_string(),
            reference_frame: node
                .attribute("ReferenceCoordinateFrame")
                .unwrap_or("Reference")
                .to_string(),
            spacing_mm: spacing,
            origin_mm,
            extent,
            clip_origin_px,
            clip_size_px,
            fan: r.fan()?,
            pixel_rejection_threshold: r.optional_number("PixelRejectionThreshold")?,
            skip_interval: r.count("SkipInterval", 1, 1_000_000)?,
            interpolation: r.choice(
                "Interpolation",
                &[
                    ("NEAREST_NEIGHBOR", Interpolation::NearestNeighbor),
                    ("LINEAR", Interpolation::Linear),
                ],
                Interpolation::NearestNeighbor,
            )?,
            compounding: r.choice(
                "CompoundingMode",
                &[
                    ("MEAN", Compounding::Mean),
                    ("LATEST", Compounding::Latest),
                    ("MAXIMUM", Compounding::Maximum),
                ],
                Compounding::Mean,
            )?,
            optimization: r.choice(
                "Optimization",
                &[
                    ("NONE", Optimization::None),
                    ("NO_OPTIMIZATION", Optimization::None),
                    ("PARTIAL", Optimization::Partial),
                    ("PARTIAL_OPTIMIZATION", Optimization::Partial),
                    ("FULL", Optimization::Full),
                    ("FULL_OPTIMIZATION", Optimization::Full),
                ],
                Optimization::Full,
            )?,
            threads: r.count("NumberOfThreads", 0, 1024)?,
            hole_filling: r.hole_filling()?,
            importance_mask: node
                .attribute("ImportanceMaskFilename")
                .map(|f| path.parent().unwrap_or(Path::new(".")).join(f)),
        })
    }
}

/// `OutputOrigin` and `OutputExtent`, where given.
type OriginExtent = (Option<[f64; 3]>, Option<[i64; 6]>);

/// Attribute readers for one element, errors naming its line.
struct Reader<'a, 'b, 'input> {
    x: &'a Xml<'b, 'input>,
    node: roxmltree::Node<'a, 'input>,
}

impl Reader<'_, '_, '_> {
    fn fail(&self, message: String) -> ConfigError {
        self.x.fail(self.node, message)
    }

    fn optional(&self, name: &str, count: usize) -> Result<Option<Vec<f64>>, ConfigError> {
        match self.node.attribute(name) {
            None => Ok(None),
            Some(_) => self.x.numbers(self.node, name, count).map(Some),
        }
    }

    fn optional_number(&self, name: &str) -> Result<Option<f64>, ConfigError> {
        Ok(self.optional(name, 1)?.map(|v| v[0]))
    }

    fn positive_triple(&self, name: &str) -> Result<Option<[f64; 3]>, ConfigError> {
        let Some(v) = self.optional(name, 3)? else {
            return Ok(None);
        };
        if v.iter().any(|s| !(*s >= MIN_SPACING_MM && *s <= MAX_SPACING_MM)) {
            return Err(self.fail(format!(
                "`{name}` must be 3 numbers in [{MIN_SPACING_MM}, {MAX_SPACING_MM}] mm, got {v:?}"
            )));
        }
        Ok(Some([v[0], v[1], v[2]]))
    }

    /// A whole number in `[least, most]`, `least` where absent.
    fn count(&self, name: &str, least: usize, most: usize) -> Result<usize, ConfigError> {
        let Some(v) = self.optional_number(name)? else {
            return Ok(least);
        };
        if v.fract() != 0.0 || v < least as f64 || v > most as f64 {
            return Err(self.fail(format!("`{name}` must be a whole number in [{least}, {most}], got {v}")));
        }
        Ok(v as usize)
    }

    fn choice<T: Copy>(&self, name: &str, options: &[(&str, T)], default: T) -> Result<T, ConfigError> {
        let Some(text) = self.node.attribute(name) else {
            return Ok(default);
        };
        options
            .iter()
            .find(|(key, _)| key.eq_ignore_ascii_case(text.trim()))
            .map(|(_, v)| *v)
            .ok_or_else(|| {
                let names: Vec<&str> = options.iter().map(|(k, _)| *k).collect();
                self.fail(format!("`{name}=\"{text}\"`: expected one of {}", names.join(", ")))
            })
    }

    fn switch(&self, name: &str) -> Result<bool, ConfigError> {
        self.choice(
            name,
            &[("ON", true), ("TRUE", true), ("OFF", false), ("FALSE", false)],
            false,
        )
    }

    /// `OutputOrigin` and `OutputExtent` together, or neither.
    fn origin_and_extent(&self) -> Result<OriginExtent, ConfigError> {
        let origin = self.optional("OutputOrigin", 3)?;
        let extent = self.optional("OutputExtent", 6)?;
        match (origin, extent) {
            (None, None) => Ok((None, None)),
            (origin, Some(e)) => {
                if e.iter().any(|v| v.fract() != 0.0 || v.abs() > 1e7) || e[0] > e[1] || e[2] > e[3] || e[4] > e[5] {
                    return Err(self.fail(format!(
                        "`OutputExtent` must be 6 whole numbers, min max per axis with min <= max, got {e:?}"
                    )));
                }
                let o = origin.unwrap_or(vec![0.0; 3]);
                Ok((Some([o[0], o[1], o[2]]), Some(std::array::from_fn(|i| e[i] as i64))))
            }
            (Some(_), None) => Err(self.fail(
                "`OutputOrigin` without `OutputExtent`: give both, or neither to fit the volume to the frames".into(),
            )),
        }
    }

    fn clip_rectangle(&self) -> Result<([usize; 2], [usize; 2]), ConfigError> {
        let mut out = [[0usize; 2]; 2];
        for (slot, name) in ["ClipRectangleOrigin", "ClipRectangleSize"].iter().enumerate() {
            if let Some(v) = self.optional(name, 2)? {
                if v.iter().any(|c| c.fract() != 0.0 || *c < 0.0 || *c > 1e6) {
                    return Err(self.fail(format!("`{name}` must be 2 whole numbers of pixels >= 0, got {v:?}")));
                }
                out[slot] = [v[0] as usize, v[1] as usize];
            }
        }
        Ok((out[0], out[1]))
    }

    fn fan(&self) -> Result<Option<Fan>, ConfigError> {
        /// Farthest fan coordinate, px: beyond any B-scan's size.
        const MAX_FAN_PX: f64 = 65_535.0;
        if self.switch("EnableFanAnglesAutoDetect")? {
            return Err(self.fail(
                "`EnableFanAnglesAutoDetect=\"TRUE\"` is not supported by probecal: give the fan's angles".into(),
            ));
        }
        let angles = self.optional("FanAnglesDeg", 2)?.unwrap_or(vec![0.0, 0.0]);
        if angles == [0.0, 0.0] {
            return Ok(None);
        }
        if !(-90.0..=90.0).contains(&angles[0]) || !(-90.0..=90.0).contains(&angles[1]) || angles[0] >= angles[1] {
            return Err(self.fail(format!(
                "`FanAnglesDeg` must be two angles within ±90° with the first below the second, got {angles:?}"
            )));
        }
        let origin = self.optional("FanOriginPixel", 2)?.unwrap_or(vec![0.0, 0.0]);
        let start = self.optional_number("FanRadiusStartPixel")?.unwrap_or(0.0);
        let stop = self.optional_number("FanRadiusStopPixel")?.unwrap_or(500.0);
        if start < 0.0 || stop <= start || stop > MAX_FAN_PX || origin.iter().any(|c| c.abs() > MAX_FAN_PX) {
            return Err(self.fail(format!(
                "`FanOriginPixel` {origin:?}, `FanRadiusStartPixel` {start} and `FanRadiusStopPixel` {stop}: need 0 <= start < stop and every one within {MAX_FAN_PX} px"
            )));
        }
        Ok(Some(Fan {
            angles_deg: [angles[0], angles[1]],
            origin_px: [origin[0], origin[1]],
            radius_start_px: start,
            radius_stop_px: stop,
        }))
    }

    fn hole_filling(&self) -> Result<Vec<HoleFilling>, ConfigError> {
        if !self.switch("FillHoles")? {
            return Ok(Vec::new());
        }
        let elements: Vec<_> = self
            .node
            .children()
            .filter(|n| n.has_tag_name("HoleFilling"))
            .flat_map(|n| n.children().filter(|c| c.has_tag_name("HoleFillingElement")))
            .collect();
        if elements.is_empty() {
            return Err(
                self.fail("`FillHoles=\"ON\"` needs <HoleFilling> with at least one <HoleFillingElement>".into())
            );
        }
        elements
            .into_iter()
            .map(|node| {
                let r = Reader { x: self.x, node };
                r.hole_filling_element()
            })
            .collect()
    }

    fn hole_filling_element(&self) -> Result<HoleFilling, ConfigError> {
        let kind = self.x.attr(self.node, "Type")?;
        let size = || -> Result<usize, ConfigError> {
            let s = self.count("Size", 1, MAX_KERNEL)?;
            if self.node.attribute("Size").is_none() || s % 2 == 0 {
                return Err(self.fail(format!("`{kind}` needs `Size`, an odd whole number up to {MAX_KERNEL}")));
            }
            Ok(s)
        };
        let ratio = || -> Result<f64, ConfigError> {
            let v = self
                .optional_number("MinimumKnownVoxelsRatio")?
                .ok_or_else(|| self.fail(format!("`{kind}` needs `MinimumKnownVoxelsRatio` (0 to 1)")))?;
            if !(0.0..=1.0).contains(&v) {
                return Err(self.fail(format!("`MinimumKnownVoxelsRatio` must lie in [0, 1], got {v}")));
            }
            Ok(v)
        };
        let stdev = || -> Result<f64, ConfigError> {
            let v = self
                .optional_number("Stdev")?
                .ok_or_else(|| self.fail(format!("`{kind}` needs `Stdev` (voxels)")))?;
            if !(v > 0.0 && v <= MAX_KERNEL as f64) {
                return Err(self.fail(format!("`Stdev` must be in (0, {MAX_KERNEL}] voxels, got {v}")));
            }
            Ok(v)
        };
        Ok(match kind {
            "STICK" => {
                if self.node.attribute("StickLengthLimit").is_none() {
                    return Err(self.fail("`STICK` needs `StickLengthLimit` (voxels)".into()));
                }
                HoleFilling::Stick {
                    length_limit: self.count("StickLengthLimit", 1, MAX_KERNEL)?,
                    sticks_to_use: self.count("NumberOfSticksToUse", 1, 13)?,
                }
            }
            "GAUSSIAN" => HoleFilling::Gaussian {
                size: size()?,
                stdev: stdev()?,
                min_known_ratio: ratio()?,
            },
            "GAUSSIAN_ACCUMULATION" => HoleFilling::GaussianAccumulation {
                size: size()?,
                stdev: stdev()?,
                min_known_ratio: ratio()?,
            },
            "NEAREST_NEIGHBOR" => HoleFilling::NearestNeighbor {
                size: size()?,
                min_known_ratio: ratio()?,
            },
            "DISTANCE_WEIGHT_INVERSE" => HoleFilling::DistanceWeightInverse {
                size: size()?,
                min_known_ratio: ratio()?,
            },
            other => {
                return Err(self.fail(format!(
                    "hole-filling `Type=\"{other}\"`: expected STICK, GAUSSIAN, GAUSSIAN_ACCUMULATION, NEAREST_NEIGHBOR or DISTANCE_WEIGHT_INVERSE"
                )))
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(attrs: &str, inner: &str) -> Result<VolumeSettings, ConfigError> {
        let text = format!(
            "<PlusConfiguration>\n<VolumeReconstruction {attrs}>\n{inner}</VolumeReconstruction>\n</PlusConfiguration>"
        );
        VolumeSettings::parse(Path::new("vr.xml"), &text)
    }

    #[test]
    fn reads_plus_settings_with_plus_defaults() {
        let s = parse(
            "OutputSpacing=\"0.5 0.5 0.5\" ClipRectangleOrigin=\"192 16\" ClipRectangleSize=\"420 580\" FanAnglesDeg=\"-45 45\" FanOriginPixel=\"380 20\" FanRadiusStartPixel=\"120\" FanRadiusStopPixel=\"360\" Interpolation=\"LINEAR\" FillHoles=\"ON\"",
            "<HoleFilling><HoleFillingElement Type=\"STICK\" StickLengthLimit=\"9\" NumberOfSticksToUse=\"1\"/></HoleFilling>\n",
        )
        .unwrap();
        assert_eq!(s.interpolation, Interpolation::Linear);
        assert_eq!(s.compounding, Compounding::Mean);
        assert_eq!(s.optimization, Optimization::Full);
        assert_eq!((s.clip_origin_px, s.clip_size_px), ([192, 16], [420, 580]));
        assert_eq!(s.fan.unwrap().radius_stop_px, 360.0);
        assert_eq!(
            s.hole_filling,
            vec![HoleFilling::Stick {
                length_limit: 9,
                sticks_to_use: 1
            }]
        );
        assert_eq!(s.skip_interval, 1);
    }

    #[test]
    fn bad_settings_name_the_attribute_and_line() {
        for (attrs, inner, want) in [
            ("", "", "needs `OutputSpacing`"),
            ("OutputSpacing=\"0.5 0 0.5\"", "", "`OutputSpacing` must be 3 numbers"),
            ("OutputSpacing=\"1 1 1\" Interpolation=\"CUBIC\"", "", "expected one of NEAREST_NEIGHBOR, LINEAR"),
            ("OutputSpacing=\"1 1 1\" FillHoles=\"ON\"", "", "needs <HoleFilling>"),
            ("OutputSpacing=\"1 1 1\" OutputOrigin=\"0 0 0\"", "", "without `OutputExtent`"),
            ("OutputSpacing=\"1 1 1\" FanAnglesDeg=\"30 -30\"", "", "first below the second"),
            ("OutputSpacing=\"1 1 1\" EnableFanAnglesAutoDetect=\"TRUE\"", "", "not supported"),
            (
                "OutputSpacing=\"1 1 1\" FillHoles=\"ON\"",
                "<HoleFilling><HoleFillingElement Type=\"GAUSSIAN\" Size=\"4\" Stdev=\"1\" MinimumKnownVoxelsRatio=\"0.5\"/></HoleFilling>\n",
                "odd whole number",
            ),
        ] {
            let e = parse(attrs, inner).unwrap_err().to_string();
            assert!(e.starts_with("vr.xml:"), "{e}");
            assert!(e.contains(want), "{attrs}: {e}");
        }
    }
}

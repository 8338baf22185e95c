//! Hostile input files: PLUS sequences, device sets (segmentation and volume
//! reconstruction), ArUco dictionaries, images and camera options.

use std::path::Path;

use super::*;

/// A small uncompressed sequence header of two 40x30 frames with `edit`
/// applied to its text, then `data` bytes of pixels.
pub(super) fn sequence(edit: impl Fn(String) -> String, data: usize) -> Vec<u8> {
    let mut text = String::from(
        "ObjectType = Image\nNDims = 3\nCompressedData = False\nDimSize = 40 30 2\nElementType = MET_UCHAR\n",
    );
    for i in 0..2 {
        text += &format!("Seq_Frame{i:04}_Timestamp = {}\n", i as f64 * 0.1);
        text += &format!("Seq_Frame{i:04}_ImageStatus = OK\n");
        text += &format!("Seq_Frame{i:04}_ProbeToTrackerTransform = 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n");
        text += &format!("Seq_Frame{i:04}_ProbeToTrackerTransformStatus = OK\n");
    }
    text += "ElementDataFile = LOCAL\n";
    let mut bytes = edit(text).into_bytes();
    bytes.extend(std::iter::repeat_n(7u8, data));
    bytes
}

/// `probecal segment <seq> --config <fCal set> --out <dir>/out`.
pub(super) fn segment(dir: &Path, seq: String) -> Vec<String> {
    vec![
        "segment".into(),
        seq,
        "--config".into(),
        s(shared_data(FCAL, FCAL_SET)),
        "--out".into(),
        s(dir.join("out")),
    ]
}

pub(super) fn sequence_case(name: &str, expect: &str, edit: fn(String) -> String, data: usize) -> Case {
    case(&format!("sequence: {name}"), 1, expect, move |d| {
        let seq = write(d, "seq.mha", &sequence(edit, data));
        segment(d, seq)
    })
}

pub(super) fn sequence_cases() -> Vec<Case> {
    const FRAMES: usize = 40 * 30 * 2;
    vec![
        case("sequence: empty file", 1, "seq.mha", |d| {
            let seq = write(d, "seq.mha", b"");
            segment(d, seq)
        }),
        case("sequence: random bytes", 1, "seq.mha", |d| {
            let bytes: Vec<u8> = (0..4096u32).map(|i| (i.wrapping_mul(2654435761) >> 13) as u8).collect();
            let seq = write(d, "seq.mha", &bytes);
            segment(d, seq)
        }),
        sequence_case(
            "no end of header",
            "seq.mha",
            |t| t.replace("ElementDataFile = LOCAL\n", ""),
            0,
        ),
        sequence_case(
            "two dimensions",
            "seq.mha:2: `NDims = 2`",
            |t| t.replace("NDims = 3", "NDims = 2"),
            FRAMES,
        ),
        sequence_case(
            "four dimensions",
            "seq.mha:2: `NDims = 4`",
            |t| t.replace("NDims = 3", "NDims = 4"),
            FRAMES,
        ),
        sequence_case("zero width", "seq.mha:4", |t| t.replace("40 30 2", "0 30 2"), FRAMES),
        sequence_case(
            "negative width",
            "seq.mha:4",
            |t| t.replace("40 30 2", "-40 30 2"),
            FRAMES,
        ),
        sequence_case(
            "size of two numbers",
            "seq.mha:2",
            |t| t.replace("40 30 2", "40 30"),
            FRAMES,
        ),
        sequence_case(
            "size beyond 64 bits",
            "seq.mha:4",
            |t| t.replace("40 30 2", "40 30 18446744073709551616"),
            FRAMES,
        ),
        sequence_case(
            "frames whose product overflows",
            "seq.mha:4",
            |t| t.replace("40 30 2", "4294967295 4294967295 4294967295"),
            FRAMES,
        ),
        sequence_case(
            "element type unknown",
            "seq.mha:5",
            |t| t.replace("MET_UCHAR", "MET_QUATERNION"),
            FRAMES,
        ),
        sequence_case(
            "three channels",
            "seq.mha",
            |t| t.replace("ElementType", "ElementNumberOfChannels = 3\nElementType"),
            FRAMES,
        ),
        sequence_case(
            "compressed size of a terabyte",
            "seq.mha",
            |t| {
                t.replace("CompressedData = False", "CompressedData = True")
                    .replace("ElementType", "CompressedDataSize = 1000000000000\nElementType")
            },
            100,
        ),
        sequence_case(
            "compressed data not zlib",
            "seq.mha",
            |t| {
                t.replace("CompressedData = False", "CompressedData = True")
                    .replace("ElementType", "CompressedDataSize = 100\nElementType")
            },
            100,
        ),
        sequence_case(
            "compressed size negative",
            "seq.mha",
            |t| {
                t.replace("CompressedData = False", "CompressedData = True")
                    .replace("ElementType", "CompressedDataSize = -5\nElementType")
            },
            100,
        ),
        sequence_case(
            "data in another file",
            "only LOCAL",
            |t| t.replace("ElementDataFile = LOCAL", "ElementDataFile = /etc/passwd"),
            0,
        ),
        sequence_case("pixels cut off", "seq.mha", |t| t, FRAMES / 2),
        sequence_case(
            "a frame past the frame count",
            "seq.mha",
            |t| t.replace("ElementType", "Seq_Frame0007_Timestamp = 3\nElementType"),
            FRAMES,
        ),
        sequence_case(
            "a frame index of twenty digits",
            "seq.mha",
            |t| {
                t.replace(
                    "ElementType",
                    "Seq_Frame99999999999999999999_Timestamp = 3\nElementType",
                )
            },
            FRAMES,
        ),
        sequence_case(
            "a frame index of ten digits",
            "seq.mha",
            |t| t.replace("ElementType", "Seq_Frame4000000000_Timestamp = 3\nElementType"),
            FRAMES,
        ),
        case("sequence: a header of 300 MB", 1, "seq.mha", |d| {
            let long = format!("Comment = {}\n", "x".repeat(300 << 20));
            let seq = write(
                d,
                "seq.mha",
                &sequence(move |t| t.replace("NDims", &format!("{long}NDims")), 0),
            );
            segment(d, seq)
        }),
        case("sequence: ten million header fields", 1, "seq.mha", |d| {
            let many: String = (0..10_000_000).map(|i| format!("F{i} = 1\n")).collect();
            let seq = write(
                d,
                "seq.mha",
                &sequence(move |t| t.replace("NDims", &format!("{many}NDims")), 0),
            );
            segment(d, seq)
        }),
        sequence_case(
            "a header line without `=`",
            "seq.mha:1",
            |t| t.replace("ObjectType = Image", "ObjectType Image"),
            FRAMES,
        ),
        sequence_case(
            "big-endian pixels",
            "seq.mha",
            |t| {
                t.replace(
                    "ElementType",
                    "BinaryDataByteOrderMSB = True\nElementType = MET_USHORT\nX",
                )
            },
            FRAMES * 2,
        ),
    ]
}

/// The fCal device set with `from` replaced by `to` as `<dir>/set.xml`.
pub(super) fn fcal_set(dir: &Path, from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(shared_data(FCAL, FCAL_SET)).unwrap();
    assert!(text.contains(from), "`{from}` is not in the fCal device set");
    write(dir, "set.xml", text.replacen(from, to, 1).as_bytes())
}

pub(super) fn device_set_case(name: &str, from: &'static str, to: &'static str, expect: &str) -> Case {
    case(&format!("device set: {name}"), 1, expect, move |d| {
        let set = fcal_set(d, from, to);
        args(&[
            "segment",
            &s(shared_data(FCAL, FCAL_VALIDATION)),
            "--config",
            &set,
            "--out",
            &s(d.join("out")),
        ])
    })
}

pub(super) fn device_set_cases() -> Vec<Case> {
    let spacing = r#"ApproximateSpacingMmPerPixel="0.078""#;
    let wire = r#"EndPointFront="30.0 0.0 20.0""#;
    vec![
        case("device set: empty file", 1, "set.xml", |d| {
            let set = write(d, "set.xml", b"");
            segment_with(d, set)
        }),
        case("device set: not XML", 1, "set.xml", |d| {
            let set = write(d, "set.xml", b"ObjectType = Image\n");
            segment_with(d, set)
        }),
        case("device set: cut off", 1, "set.xml", |d| {
            let text = std::fs::read(shared_data(FCAL, FCAL_SET)).unwrap();
            let set = write(d, "set.xml", &text[..text.len() / 2]);
            segment_with(d, set)
        }),
        case("device set: entities that expand a billion times", 1, "set.xml", |d| {
            let mut doc = String::from("<?xml version=\"1.0\"?>\n<!DOCTYPE lolz [\n<!ENTITY lol \"lol\">\n");
            for k in 1..10 {
                let prev = if k == 1 {
                    "lol".to_string()
                } else {
                    format!("lol{}", k - 1)
                };
                doc += &format!("<!ENTITY lol{k} \"{}\">\n", format!("&{prev};").repeat(10));
            }
            doc += "]>\n<PlusConfiguration a=\"&lol9;\"/>\n";
            let set = write(d, "set.xml", doc.as_bytes());
            segment_with(d, set)
        }),
        case("device set: 80 MB", 1, "set.xml", |d| {
            let doc = format!("<PlusConfiguration a=\"{}\"/>", "x".repeat(80 << 20));
            let set = write(d, "set.xml", doc.as_bytes());
            segment_with(d, set)
        }),
        device_set_case("no phantom", "<PhantomDefinition>", "<NotThePhantom>", "set.xml"),
        device_set_case(
            "wire end of two numbers",
            wire,
            r#"EndPointFront="30.0 0.0""#,
            "set.xml",
        ),
        device_set_case(
            "wire end not a number",
            wire,
            r#"EndPointFront="30.0 nan 20.0""#,
            "set.xml",
        ),
        device_set_case(
            "wire end infinite",
            wire,
            r#"EndPointFront="30.0 1e400 20.0""#,
            "set.xml",
        ),
        device_set_case(
            "spacing zero",
            spacing,
            r#"ApproximateSpacingMmPerPixel="0""#,
            "set.xml",
        ),
        device_set_case(
            "spacing negative",
            spacing,
            r#"ApproximateSpacingMmPerPixel="-0.078""#,
            "set.xml",
        ),
        device_set_case(
            "spacing not a number",
            spacing,
            r#"ApproximateSpacingMmPerPixel="nan""#,
            "set.xml",
        ),
        device_set_case(
            "clip origin negative",
            r#"ClipRectangleOrigin="27 27""#,
            r#"ClipRectangleOrigin="-27 27""#,
            "set.xml",
        ),
        device_set_case(
            "clip size zero",
            r#"ClipRectangleSize="766 562""#,
            r#"ClipRectangleSize="0 562""#,
            "set.xml:87",
        ),
        device_set_case(
            "opening disk a kilometre wide",
            r#"MorphologicalOpeningCircleRadiusMm="0.27""#,
            r#"MorphologicalOpeningCircleRadiusMm="1e6""#,
            "set.xml",
        ),
        device_set_case(
            "opening bar a kilometre long",
            r#"MorphologicalOpeningBarSizeMm="2.0""#,
            r#"MorphologicalOpeningBarSizeMm="1e6""#,
            "set.xml",
        ),
        device_set_case(
            "threshold over 100 %",
            r#"ThresholdImagePercent="10""#,
            r#"ThresholdImagePercent="250""#,
            "set.xml",
        ),
        device_set_case(
            "a trillion dot candidates",
            r#"NumberOfMaximumFiducialPointCandidates="20""#,
            r#"NumberOfMaximumFiducialPointCandidates="1000000000000""#,
            "set.xml",
        ),
        device_set_case(
            "line distance tolerance not a number",
            r#"MaxLinePairDistanceErrorPercent="10""#,
            r#"MaxLinePairDistanceErrorPercent="nan""#,
            "set.xml",
        ),
        device_set_case(
            "angle tolerance negative",
            r#"AngleToleranceDegrees="10""#,
            r#"AngleToleranceDegrees="-10""#,
            "set.xml",
        ),
        device_set_case(
            "collinearity tolerance negative",
            r#"CollinearPointsMaxDistanceFromLineMm="0.6""#,
            r#"CollinearPointsMaxDistanceFromLineMm="-0.6""#,
            "set.xml",
        ),
        device_set_case(
            "theta range inverted",
            r#"MinThetaDegrees="-70""#,
            r#"MinThetaDegrees="170""#,
            "set.xml",
        ),
    ]
}

pub(super) fn segment_with(dir: &Path, set: String) -> Vec<String> {
    args(&[
        "segment",
        &s(shared_data(FCAL, FCAL_VALIDATION)),
        "--config",
        &set,
        "--out",
        &s(dir.join("out")),
    ])
}

/// `probecal reconstruct` of the spine sweep with its device set's
/// `<VolumeReconstruction ` attributes led by `attributes`.
pub(super) fn volume_case(name: &str, from: &'static str, to: &'static str, expect: &str) -> Case {
    case(&format!("reconstruct: {name}"), 2, expect, move |d| {
        let text = std::fs::read_to_string(shared_data(VOLUME, VOLUME_SET)).unwrap();
        assert!(text.contains(from), "`{from}` is not in the volume device set");
        let set = write(d, "volume.xml", text.replacen(from, to, 1).as_bytes());
        args(&[
            "reconstruct",
            &s(shared_data(VOLUME, SWEEP)),
            "--config",
            &set,
            "--out",
            &s(d.join("out")),
        ])
    })
}

pub(super) fn volume_cases() -> Vec<Case> {
    let spacing = r#"OutputSpacing="0.5 0.5 0.5""#;
    let hole = r#"StickLengthLimit="9""#;
    vec![
        volume_case("spacing zero", spacing, r#"OutputSpacing="0 0.5 0.5""#, "volume.xml"),
        volume_case(
            "spacing of a micrometre",
            spacing,
            r#"OutputSpacing="0.001 0.001 0.001""#,
            "volume.xml",
        ),
        volume_case(
            "spacing not a number",
            spacing,
            r#"OutputSpacing="nan 0.5 0.5""#,
            "volume.xml",
        ),
        volume_case(
            "extent of a trillion voxels",
            spacing,
            r#"OutputSpacing="0.5 0.5 0.5" OutputExtent="0 9999 0 9999 0 9999""#,
            "volume.xml",
        ),
        volume_case(
            "origin not a number",
            spacing,
            r#"OutputSpacing="0.5 0.5 0.5" OutputOrigin="nan 0 0""#,
            "volume.xml",
        ),
        volume_case("interpolation unknown", "NEAREST_NEIGHBOR", "CUBIC", "volume.xml"),
        volume_case(
            "compounding unknown",
            r#"CompoundingMode="MEAN""#,
            r#"CompoundingMode="MEDIAN""#,
            "volume.xml",
        ),
        volume_case(
            "clip past the image",
            r#"ClipRectangleSize="820 616""#,
            r#"ClipRectangleSize="9000 616""#,
            "volume.xml",
        ),
        volume_case(
            "fan angles not numbers",
            spacing,
            r#"OutputSpacing="0.5 0.5 0.5" FanAnglesDeg="nan 30""#,
            "volume.xml",
        ),
        volume_case(
            "fan radius of a kilometre of pixels",
            spacing,
            r#"OutputSpacing="0.5 0.5 0.5" FanAnglesDeg="-30 30" FanOriginPixel="410 0" FanRadiusStartPixel="0" FanRadiusStopPixel="1e12""#,
            "volume.xml",
        ),
        volume_case(
            "skip interval zero",
            spacing,
            r#"OutputSpacing="0.5 0.5 0.5" SkipInterval="0""#,
            "volume.xml",
        ),
        volume_case(
            "rejection threshold not a number",
            spacing,
            r#"OutputSpacing="0.5 0.5 0.5" PixelRejectionThreshold="nan""#,
            "volume.xml",
        ),
        volume_case(
            "hole-filling stick a million long",
            hole,
            r#"StickLengthLimit="1000000""#,
            "volume.xml",
        ),
        volume_case(
            "hole-filling sticks a million",
            r#"NumberOfSticksToUse="1""#,
            r#"NumberOfSticksToUse="1000000""#,
            "volume.xml",
        ),
        volume_case(
            "hole-filling element unknown",
            r#"Type="STICK""#,
            r#"Type="SPLINE""#,
            "volume.xml",
        ),
    ]
}

/// A file in `dir` whose OpenCV FileStorage text is `body`.
pub(super) fn dictionary_case(name: &str, body: &'static str) -> Case {
    case(&format!("dictionary: {name}"), 2, "dict.yml", move |d| {
        let dict = write(d, "dict.yml", body.as_bytes());
        charuco(d, &dict)
    })
}

pub(super) fn charuco(d: &Path, dictionary: &str) -> Vec<String> {
    args(&[
        "calibrate-camera",
        "--charuco",
        "5x7",
        "--square-mm",
        "30",
        "--marker-mm",
        "20",
        "--dictionary",
        dictionary,
        "--out",
        &s(d.join("out/camera.yml")),
        &s(shared_data("opencv-aruco", "choriginal.jpg")),
    ])
}

pub(super) fn camera(d: &Path, extra: &[&str]) -> Vec<String> {
    let mut a = args(&["calibrate-camera", "--out", &s(d.join("out/camera.yml"))]);
    a.extend(args(extra));
    a
}

pub(super) fn camera_cases() -> Vec<Case> {
    let left = || s(shared_data("opencv-chessboard", "left01.jpg"));
    let board = move |d: &Path, b: &str| camera(d, &["--board", b, "--square-mm", "25", &left()]);
    vec![
        case("dictionary: nested 10 000 deep", 2, "dict.yml", |d| {
            let body = format!("%YAML:1.0\n---\na: {}{}\n", "[".repeat(10_000), "]".repeat(10_000));
            let dict = write(d, "dict.yml", body.as_bytes());
            charuco(d, &dict)
        }),
        dictionary_case("markers of 1000 bits a side", "%YAML:1.0\n---\nnmarkers: 10\nmarkersize: 1000\nmaxCorrectionBits: 1\nmarker_0: \"0\"\n"),
        dictionary_case("a billion markers", "%YAML:1.0\n---\nnmarkers: 1000000000\nmarkersize: 4\nmaxCorrectionBits: 1\nmarker_0: \"0101010101010101\"\n"),
        dictionary_case("marker bits not bits", "%YAML:1.0\n---\nnmarkers: 1\nmarkersize: 4\nmaxCorrectionBits: 1\nmarker_0: \"0101xyz101010101\"\n"),
        dictionary_case("not FileStorage", "nmarkers = 3\n"),
        case("camera: board of no corners", 2, "--board", move |d| board(d, "0x6")),
        case("camera: board of one corner", 2, "--board", move |d| board(d, "1x1")),
        case("camera: board of three numbers", 2, "--board", move |d| board(d, "9x6x2")),
        case("camera: board negative", 2, "-9", move |d| board(d, "-9x6")),
        case("camera: board past 32 bits", 2, "--board", move |d| board(d, "4294967297x6")),
        case("camera: square not a number", 2, "--square-mm", move |d| {
            camera(d, &["--board", "9x6", "--square-mm", "nan", &left()])
        }),
        case("camera: square infinite", 2, "--square-mm", move |d| {
            camera(d, &["--board", "9x6", "--square-mm", "inf", &left()])
        }),
        case("camera: square of 1e300 mm", 2, "--square-mm must be", move |d| {
            camera(d, &["--board", "9x6", "--square-mm", "1e300", &left()])
        }),
        case("camera: marker larger than its square", 2, "--marker-mm", move |d| {
            let mut a = charuco(d, "DICT_6X6_250");
            let k = a.iter().position(|x| x == "20").unwrap();
            a[k] = "40".into();
            a
        }),
        case("camera: dictionary of no such name", 2, "DICT_9X9_1", move |d| charuco(d, "DICT_9X9_1")),
        case("camera: an image of 0 bytes", 1, "empty.png", move |d| {
            let img = write(d, "empty.png", b"");
            camera(d, &["--board", "9x6", "--square-mm", "25", &img])
        }),
        case("camera: a PNG that claims 100000 x 100000 px", 1, "bomb.png", move |d| {
            let mut png = b"\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR".to_vec();
            png.extend(100_000u32.to_be_bytes());
            png.extend(100_000u32.to_be_bytes());
            png.extend([8, 0, 0, 0, 0, 0, 0, 0, 0]);
            let img = write(d, "bomb.png", &png);
            camera(d, &["--board", "9x6", "--square-mm", "25", &img])
        }),
        case("camera: a BMP (refused by its format, before its size)", 1, "a BMP file; probecal reads PNG and JPEG", move |d| {
            let mut bmp = b"BM".to_vec();
            bmp.extend([0u8; 16]);
            bmp.extend(30_000i32.to_le_bytes());
            bmp.extend(30_000i32.to_le_bytes());
            bmp.extend([1, 0, 24, 0]);
            bmp.extend([0u8; 24]);
            let img = write(d, "bomb.bmp", &bmp);
            camera(d, &["--board", "9x6", "--square-mm", "25", &img])
        }),
        case("camera: a PNM, whose header is not read", 1, "image.png", move |d| {
            let img = write(d, "image.png", b"P5\n30000 30000\n255\n");
            camera(d, &["--board", "9x6", "--square-mm", "25", &img])
        }),
        case("camera: output onto its image", 2, "left01.jpg", move |d| {
            let img = write(d, "left01.jpg", &std::fs::read(shared_data("opencv-chessboard", "left01.jpg")).unwrap());
            args(&["calibrate-camera", "--board", "9x6", "--square-mm", "25", "--out", &img, &img])
        }),
    ]
}

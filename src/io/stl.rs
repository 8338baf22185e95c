//! Binary STL: a triangle soup with outward facet normals, millimetres.

use std::path::Path;

use nalgebra::Point3;

/// A triangle, vertices counter-clockwise seen from outside.
pub type Triangle = [Point3<f64>; 3];

/// Triangles of one STL file are bounded (a phantom needs tens of thousands).
pub const MAX_TRIANGLES: usize = 5_000_000;

#[derive(Debug, thiserror::Error)]
pub enum StlError {
    #[error(transparent)]
    Write(#[from] crate::io::fs::WriteError),
    #[error("{count} triangles exceed the limit of {MAX_TRIANGLES}")]
    TooMany { count: usize },
    #[error("triangle {index} has a coordinate that is not finite")]
    NotFinite { index: usize },
}

/// The bytes of a binary STL of `triangles` (normals from the vertex order).
pub fn to_bytes(header: &str, triangles: &[Triangle]) -> Result<Vec<u8>, StlError> {
    if triangles.len() > MAX_TRIANGLES {
        return Err(StlError::TooMany { count: triangles.len() });
    }
    let mut out = Vec::with_capacity(84 + 50 * triangles.len());
    let mut head = [b' '; 80];
    for (h, b) in head.iter_mut().zip(header.bytes()) {
        *h = b;
    }
    out.extend_from_slice(&head);
    out.extend_from_slice(&(triangles.len() as u32).to_le_bytes());
    for (index, t) in triangles.iter().enumerate() {
        if t.iter().any(|p| !p.coords.iter().all(|v| v.is_finite())) {
            return Err(StlError::NotFinite { index });
        }
        let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
        let n = if n.norm() > 0.0 { n.normalize() } else { n };
        for v in n.iter().chain(t.iter().flat_map(|p| p.coords.iter())) {
            out.extend_from_slice(&(*v as f32).to_le_bytes());
        }
        out.extend_from_slice(&[0, 0]);
    }
    Ok(out)
}

/// Writes a binary STL; the file appears whole or not at all.
pub fn write(path: &Path, header: &str, triangles: &[Triangle]) -> Result<(), StlError> {
    Ok(crate::io::fs::write_atomic(path, &to_bytes(header, triangles)?)?)
}

//! Which voxels have a marked voxel within a cube around them: the holes a
//! stick of limited length can reach (a stick's steps move at most one voxel
//! along each axis, so whatever it reaches lies in the cube of its limit).

/// 1 where `mask` (0 or 1, `dims` voxels in x-fastest order) has a 1 within
/// `radius` steps along every axis (the cube of side `2·radius + 1`), else 0.
/// Three separable passes, each a forward and a backward sweep of distances
/// (saturating at 255); the y and z sweeps go a row or a plane at a time.
pub fn within_cube(mask: &[u8], dims: [usize; 3], radius: usize) -> Vec<u8> {
    let [nx, ny, nz] = dims;
    assert_eq!(mask.len(), nx * ny * nz, "mask and dims disagree");
    let radius = radius.min(254) as u8;
    let mut out = mask.to_vec();
    let mut dist = vec![0u8; out.len()];
    // Along x: one row at a time.
    for row in out.chunks_exact_mut(nx.max(1)) {
        let mut d = 255u8;
        for (v, slot) in row.iter().zip(dist.iter_mut()) {
            d = if *v != 0 { 0 } else { d.saturating_add(1) };
            *slot = d;
        }
        let mut d = 255u8;
        for (k, v) in row.iter_mut().enumerate().rev() {
            d = if *v != 0 { 0 } else { d.saturating_add(1) };
            *v = u8::from(d.min(dist[k]) <= radius);
        }
    }
    // Along y within each plane, then along z: blocks of a row and of a plane.
    for z in 0..nz {
        let plane = &mut out[z * nx * ny..(z + 1) * nx * ny];
        along_blocks(plane, &mut dist[..nx * ny], nx, radius);
    }
    along_blocks(&mut out, &mut dist, nx * ny, radius);
    out
}

/// `data` as consecutive blocks of `block` values: each position dilated by
/// `radius` across the blocks (position k of block j against position k of
/// the blocks within `radius` of j). `dist` is scratch of `data`'s length.
fn along_blocks(data: &mut [u8], dist: &mut [u8], block: usize, radius: u8) {
    if block == 0 {
        return;
    }
    let blocks = data.len() / block;
    // Forward: steps since the last 1 in an earlier (or this) block.
    for j in 0..blocks {
        let (before, here) = dist.split_at_mut(j * block);
        let here = &mut here[..block];
        let values = &data[j * block..(j + 1) * block];
        if j == 0 {
            for (d, &v) in here.iter_mut().zip(values) {
                *d = if v != 0 { 0 } else { 255 };
            }
        } else {
            let previous = &before[(j - 1) * block..];
            for ((d, &p), &v) in here.iter_mut().zip(previous).zip(values) {
                *d = if v != 0 { 0 } else { p.saturating_add(1) };
            }
        }
    }
    // Backward: steps to the next 1 in a later block, carried in `ahead`.
    let mut ahead = vec![255u8; block];
    for j in (0..blocks).rev() {
        let values = &mut data[j * block..(j + 1) * block];
        let forward = &dist[j * block..(j + 1) * block];
        for ((v, a), &f) in values.iter_mut().zip(ahead.iter_mut()).zip(forward) {
            *a = if *v != 0 { 0 } else { a.saturating_add(1) };
            *v = u8::from((*a).min(f) <= radius);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cube_is_found_as_by_looking() {
        let dims = [13usize, 9, 11];
        let n = dims.iter().product::<usize>();
        let mut state = 99u64;
        for one_in in [7u64, 60, 400] {
            let mask: Vec<u8> = (0..n)
                .map(|_| {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    u8::from((state >> 33).is_multiple_of(one_in))
                })
                .collect();
            for radius in [0, 1, 2, 3, 5, 9] {
                let got = within_cube(&mask, dims, radius);
                let mut near = 0;
                for (i, &g) in got.iter().enumerate() {
                    let p = [i % dims[0], (i / dims[0]) % dims[1], i / (dims[0] * dims[1])];
                    let expected = (0..n).any(|j| {
                        let q = [j % dims[0], (j / dims[0]) % dims[1], j / (dims[0] * dims[1])];
                        mask[j] != 0 && (0..3).all(|k| p[k].abs_diff(q[k]) <= radius)
                    });
                    assert_eq!(g, u8::from(expected), "voxel {p:?}, radius {radius}, one in {one_in}");
                    near += usize::from(expected);
                }
                assert!(
                    radius > 2 || one_in != 400 || near < n,
                    "the sparse mask leaves voxels out of reach"
                );
            }
        }
    }
}

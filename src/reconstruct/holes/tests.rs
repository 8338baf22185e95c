//! Unit tests of hole filling.

use super::*;

/// The tabled sticks equal the voxel-by-voxel search on a sparse random
/// volume, whatever the limit and the slab.
#[test]
fn tabled_sticks_equal_the_search_voxel_by_voxel() {
    let grid = Grid {
        origin_mm: [0.0; 3],
        spacing_mm: [1.0; 3],
        dims: [17, 13, 11],
    };
    let n = 17 * 13 * 11;
    let mut state = 12345u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 33) as u32
    };
    let (dirs, plane) = (stick_directions(grid.dims), 17 * 13);
    let mut sticks = 0;
    // One voxel in 10 filled, then one in 300 (most holes out of every stick's reach).
    for one_in in [10, 300] {
        let mut voxels = vec![0u8; n];
        let mut weights = vec![0u16; n];
        for i in 0..n {
            if next() % one_in == 0 {
                weights[i] = 256;
                voxels[i] = (next() % 256) as u8;
            }
        }
        let source = Source {
            grid: &grid,
            voxels: &voxels,
            weights: &weights,
        };
        for limit in [1, 2, 4, 9] {
            for (z0, z1) in [(0, 11), (0, 4), (4, 9), (9, 11)] {
                let mut table = stick_table(&source, z0, z1, limit, &dirs);
                for k in 0..(z1 - z0) * plane {
                    let i = z0 * plane + k;
                    let value = table.at(k);
                    if weights[i] != 0 {
                        assert_eq!(value, None, "a filled voxel is not a hole");
                        continue;
                    }
                    let p = [(i % 17) as i64, ((i / 17) % 13) as i64, (i / plane) as i64];
                    assert_eq!(value, source.stick(i, p, limit, 1, &dirs), "voxel {p:?}, limit {limit}");
                    sticks += usize::from(value.is_some());
                }
            }
        }
    }
    assert!(sticks > 1000, "{sticks} sticks only");
}

#[test]
fn a_stick_fills_the_gap_between_two_filled_planes() {
    // 1 x 1 x 5 column: 10 at z=0, 50 at z=4, holes between.
    let grid = Grid {
        origin_mm: [0.0; 3],
        spacing_mm: [1.0; 3],
        dims: [1, 1, 5],
    };
    let mut voxels = vec![10u8, 0, 0, 0, 50];
    let weights = vec![256u16, 0, 0, 0, 256];
    let stick = HoleFilling::Stick {
        length_limit: 9,
        sticks_to_use: 1,
    };
    let stats = fill(&grid, &mut voxels, &weights, &[stick], 2);
    assert_eq!(stats.holes_before, 3);
    assert_eq!(stats.holes_after, 0);
    // Ahead (towards z=4) k, behind counted one longer: value = 50·t + 10·(1−t),
    // t = (behind+1)/(ahead+behind+1).
    assert_eq!(voxels, vec![10, 26, 34, 42, 50]);
    // `StickLengthLimit` bounds the whole stick, ahead + behind + 1 steps: in
    // 10, _, 30, _, _, 50 the hole at z=1 has a stick of 3 steps, those at z=3
    // and z=4 of 4. Holes may hold a value (weights that rounded to nothing):
    // those left unfilled are emptied, with the tabled sticks (one stick) and
    // with the search hole by hole (two), on one slab or two.
    let column = Grid {
        origin_mm: [0.0; 3],
        spacing_mm: [1.0; 3],
        dims: [1, 1, 6],
    };
    let weights = vec![256u16, 0, 256, 0, 0, 256];
    for (length_limit, expected, unfilled) in [
        (4, vec![10u8, 23, 30, 40, 45, 50], 0),
        (3, vec![10, 23, 30, 0, 0, 50], 2),
        (2, vec![10, 0, 30, 0, 0, 50], 3),
    ] {
        for (sticks_to_use, threads) in [(1, 1), (1, 2), (2, 1), (2, 2)] {
            let mut voxels = vec![10u8, 7, 30, 7, 7, 50];
            let stick = HoleFilling::Stick {
                length_limit,
                sticks_to_use,
            };
            let stats = fill(&column, &mut voxels, &weights, &[stick], threads);
            let case = format!("limit {length_limit}, {sticks_to_use} sticks, {threads} threads");
            assert_eq!(stats.holes_after, unfilled, "{case}");
            assert_eq!(voxels, expected, "{case}");
        }
    }
}

/// Sticks as short as the shortest are averaged, each taken as a voxel stores it
/// (8-bit: floored) before the mean is: 16 and 41 give 28, where the mean of
/// the unrounded values (16.67 and 41.67) would give 29.
#[test]
fn tied_sticks_are_averaged_as_voxels() {
    // A 3 x 3 plane, the hole at its centre between 10 | 20 along x and 39 | 43 along y.
    let grid = Grid {
        origin_mm: [0.0; 3],
        spacing_mm: [1.0; 3],
        dims: [3, 3, 1],
    };
    let (centre, left, right, below, above) = (4, 3, 5, 1, 7);
    let mut weights = vec![0u16; 9];
    let mut voxels = vec![0u8; 9];
    for (i, v) in [(left, 10), (right, 20), (below, 39), (above, 43)] {
        weights[i] = 256;
        voxels[i] = v;
    }
    for sticks_to_use in [1, 2] {
        let mut filled = voxels.clone();
        let stick = HoleFilling::Stick {
            length_limit: 9,
            sticks_to_use,
        };
        fill(&grid, &mut filled, &weights, &[stick], 1);
        // Along x: 20·2/3 + 10/3 = 16.67 → 16; along y: 43·2/3 + 39/3 = 41.67 → 41.
        assert_eq!(filled[centre], 28, "{sticks_to_use} sticks");
    }
}

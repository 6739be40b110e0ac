//! Disjoint pieces of the cell array for data-parallel phases (rayon): each piece is a
//! contiguous run of cells with the sorted cell indices that fall in it, so each worker owns its
//! cells exactly and results do not depend on how the work was cut.

/// How many items a piece takes: at least `min`, and about eight pieces per thread.
fn piece_len(len: usize, min: usize) -> usize {
    min.max(len.div_ceil(8 * rayon::current_num_threads())).max(1)
}

/// Cut `cells` at the strictly increasing indices `idx` into pieces of about the same number of
/// indices: `(cells of the piece, index of its first cell, the indices in it)`.
pub fn tiles<'a, T>(mut cells: &'a mut [T], idx: &'a [u32], min: usize) -> Vec<(&'a mut [T], usize, &'a [u32])> {
    let mut out = Vec::new();
    let mut base = 0usize;
    for chunk in idx.chunks(piece_len(idx.len(), min)) {
        let end = chunk[chunk.len() - 1] as usize + 1;
        let (head, tail) = std::mem::take(&mut cells).split_at_mut(end - base);
        out.push((head, base, chunk));
        cells = tail;
        base = end;
    }
    out
}

/// Cut `cells` and `items` (sorted by the cell index `at(item)`) together into pieces that never
/// separate two items of the same cell: `(cells of the piece, its first cell, its items)`.
pub fn grouped<'a, T, O>(
    mut cells: &'a mut [T],
    mut items: &'a mut [O],
    min: usize,
    at: impl Fn(&O) -> usize,
) -> Vec<(&'a mut [T], usize, &'a mut [O])> {
    let per = piece_len(items.len(), min);
    let mut out = Vec::new();
    let mut base = 0usize;
    while !items.is_empty() {
        let mut cut = per.min(items.len());
        while cut < items.len() && at(&items[cut]) == at(&items[cut - 1]) {
            cut += 1;
        }
        let end = at(&items[cut - 1]) + 1;
        let (head, tail) = std::mem::take(&mut items).split_at_mut(cut);
        let (ch, ct) = std::mem::take(&mut cells).split_at_mut(end - base);
        out.push((ch, base, head));
        items = tail;
        cells = ct;
        base = end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pieces_cover_every_index_once_with_its_own_cell() {
        let mut cells: Vec<u32> = (0..1000).collect();
        let idx: Vec<u32> = (0..1000).filter(|i| i % 7 == 3 || i % 11 == 0).collect();
        let mut seen = Vec::new();
        for (tile, base, ix) in tiles(&mut cells, &idx, 5) {
            for &i in ix {
                assert_eq!(tile[i as usize - base], i);
                seen.push(i);
            }
        }
        assert_eq!(seen, idx);
        let mut items: Vec<u32> = idx.iter().flat_map(|&i| [i, i, i]).collect();
        let mut seen = Vec::new();
        for (tile, base, group) in grouped(&mut cells, &mut items, 4, |&o| o as usize) {
            let mut here: Vec<u32> = group.to_vec();
            here.dedup();
            for &o in &here {
                assert_eq!(tile[o as usize - base], o);
                assert_eq!(group.iter().filter(|&&g| g == o).count(), 3, "a cell's items stay together");
            }
            seen.extend(here);
        }
        assert_eq!(seen, idx);
    }
}

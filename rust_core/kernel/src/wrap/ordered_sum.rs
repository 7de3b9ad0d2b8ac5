//! Parallel sums that come out the same to the bit however many threads run them and whoever
//! steals what.
//!
//! Rayon's `sum` and `reduce` add their pieces in a tree whose shape follows the pool's size and
//! the work stealing of the moment, and floating-point addition is not associative: the same sum
//! could differ in its last bits from one run to the next, and the wrap's energy (which ends its
//! levels) with it. Here the terms are cut into pieces of a fixed size, each piece summed in
//! order, and the pieces' sums added in order.

use std::ops::Add;

use rayon::prelude::*;

/// Terms per piece: large enough to amortise a task, small enough to share among threads.
pub(crate) const PIECE: usize = 4096;

/// `term(0) + term(1) + … + term(count - 1)`, grouped the same way whatever the threads.
pub(crate) fn ordered_sum<T, F>(count: usize, term: F) -> T
where
    T: Copy + Default + Send + Add<Output = T>,
    F: Fn(usize) -> T + Sync,
{
    let pieces: Vec<T> = (0..count.div_ceil(PIECE))
        .into_par_iter()
        .map(|piece| {
            let end = ((piece + 1) * PIECE).min(count);
            (piece * PIECE..end).fold(T::default(), |sum, index| sum + term(index))
        })
        .collect();
    add_in_order(pieces)
}

/// The pieces' sums added in order (the last step of every sum here).
pub(crate) fn add_in_order<T: Default + Add<Output = T>>(pieces: Vec<T>) -> T {
    pieces
        .into_iter()
        .fold(T::default(), |sum, piece| sum + piece)
}

/// `ordered_sum` over items that each term may change: `term(index, &mut items[index])`, grouped
/// exactly as `ordered_sum` groups them.
pub(crate) fn ordered_sum_mut<T, U, F>(items: &mut [U], term: F) -> T
where
    T: Copy + Default + Send + Add<Output = T>,
    U: Send,
    F: Fn(usize, &mut U) -> T + Sync,
{
    let pieces: Vec<T> = items
        .par_chunks_mut(PIECE)
        .enumerate()
        .map(|(piece, chunk)| {
            chunk
                .iter_mut()
                .enumerate()
                .fold(T::default(), |sum, (offset, item)| {
                    sum + term(piece * PIECE + offset, item)
                })
        })
        .collect();
    add_in_order(pieces)
}

/// `run()` in a fresh rayon pool of each size in `threads`: the results, in that order (for tests
/// that a computation repeats to the bit whatever the pool).
#[cfg(test)]
pub(crate) fn in_pools<R: Send>(threads: &[usize], run: impl Fn() -> R + Sync) -> Vec<R> {
    threads
        .iter()
        .map(|&threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(&run)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sum_is_the_same_to_the_bit_in_every_pool() {
        // Terms of very different sizes: any change of grouping shows in the last bits.
        let terms: Vec<f64> = (0..50_000u32)
            .map(|index| f64::from((index * 7919) % 1000) * 10f64.powi((index % 17) as i32 - 8))
            .collect();
        let sums = in_pools(&[1, 2, 3, 5], || {
            ordered_sum(terms.len(), |index| terms[index]).to_bits()
        });
        assert!(sums.iter().all(|&sum| sum == sums[0]), "{sums:?}");
        let exact: f64 = terms.iter().sum();
        assert!((f64::from_bits(sums[0]) - exact).abs() <= exact * 1e-12);
        assert_eq!(ordered_sum(0, |index| terms[index]), 0.0);
        let mut items = terms.clone();
        let changed = ordered_sum_mut(&mut items, |index, item: &mut f64| {
            *item = terms[index] * 2.0;
            terms[index]
        });
        assert_eq!(changed.to_bits(), sums[0], "grouped as ordered_sum");
        assert!(
            items
                .iter()
                .zip(&terms)
                .all(|(item, term)| *item == term * 2.0)
        );
    }
}

//! Blocked holdout: the run cut into K contiguous blocks; each block is scored by a model
//! identified on the others, and the scores pooled over the whole run.
//!
//! Contiguous blocks (not random samples) keep neighbouring, correlated samples out of
//! the training set of the block they belong to, so the score is out of sample in time.

use std::ops::Range;

use super::*;

/// Block `b` of `K` over `n` samples: `[b n / K, (b + 1) n / K)`.
pub fn holdout_blocks(n: usize, blocks: usize) -> Result<Vec<Range<usize>>, AnalysisError> {
    if blocks < 2 {
        return Err(invalid("holdout", format!("needs at least 2 blocks, got {blocks}")));
    }
    // `n / 20` blocks at most (no product to overflow for a huge `blocks`).
    if blocks > n / 20 {
        let needed = blocks.saturating_mul(20);
        return Err(AnalysisError::TooShort { what: "holdout blocks (20 samples each)", needed, got: n });
    }
    Ok((0..blocks).map(|b| b * n / blocks..(b + 1) * n / blocks).collect())
}

/// Every row outside `block`.
pub fn training_rows(n: usize, block: &Range<usize>) -> Vec<usize> {
    (0..block.start).chain(block.end..n).collect()
}

/// Pooled out-of-sample metrics: `predict_block(b, block)` returns the prediction of the
/// reference on `block` from a model identified without it.
pub fn blocked_holdout<F>(reference: &[f64], blocks: usize, mut predict_block: F) -> Result<FitMetrics, AnalysisError>
where
    F: FnMut(usize, &Range<usize>) -> Result<Vec<f64>, AnalysisError>,
{
    let ranges = holdout_blocks(reference.len(), blocks)?;
    let mut pooled = Vec::with_capacity(reference.len());
    for (b, r) in ranges.iter().enumerate() {
        let p = predict_block(b, r)?;
        if p.len() != r.len() {
            return Err(invalid("holdout", format!("block {b} predicted {} samples, has {}", p.len(), r.len())));
        }
        pooled.extend(p);
    }
    Ok(FitMetrics::of(&pooled, reference))
}

impl FitMetrics {
    /// The NRMSE fit, % (100 = perfect, 0 = no better than the reference's mean):
    /// `100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖) = 100 (1 − √(1 − R²))`.
    pub fn nrmse_fit_percent(&self) -> f64 {
        100.0 * (1.0 - (1.0 - self.r_squared).max(0.0).sqrt())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_cover_the_run_and_scores_pool() {
        let b = holdout_blocks(103, 5).unwrap();
        assert_eq!(b.first().unwrap().start, 0);
        assert_eq!(b.last().unwrap().end, 103);
        assert!(b.windows(2).all(|w| w[0].end == w[1].start));
        assert!(holdout_blocks(50, 5).is_err() && holdout_blocks(100, 1).is_err());
        let t = training_rows(10, &(3..6));
        assert_eq!(t, vec![0, 1, 2, 6, 7, 8, 9]);
        // A model that predicts each block's mean of the other blocks: worse than the mean.
        let y: Vec<f64> = (0..100).map(|k| k as f64).collect();
        let m = blocked_holdout(&y, 4, |_, r| {
            let rest: Vec<f64> = training_rows(100, r).iter().map(|&k| y[k]).collect();
            let mean = rest.iter().sum::<f64>() / rest.len() as f64;
            Ok(vec![mean; r.len()])
        })
        .unwrap();
        assert!(m.r_squared < 0.0, "{m:?}");
        let exact = blocked_holdout(&y, 4, |_, r| Ok(r.clone().map(|k| k as f64).collect())).unwrap();
        assert_eq!(exact.r_squared, 1.0);
        assert_eq!(exact.nrmse_fit_percent(), 100.0);
    }
}

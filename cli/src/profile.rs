//! Dolan-More performance profiles (seed 000 section 7.2) and the summary statistics built on
//! the same table of times.
//!
//! `t[p][s]` is the time solver `s` needs to solve problem `p` at one tolerance, infinite on
//! failure. The ratio is `r[p][s] = t[p][s] / min_s t[p][s]` (infinite when every solver
//! failed on `p`), and `rho_s(tau) = |{p : r[p][s] <= tau}| / n_p`.

/// Median, with infinities sorting last (a majority of failures gives infinity); NaN when
/// `xs` is empty.
pub fn median(xs: &[f64]) -> f64 {
    if xs.is_empty() {
        return f64::NAN;
    }
    let mut v = xs.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        let (a, b) = (v[n / 2 - 1], v[n / 2]);
        if a.is_infinite() || b.is_infinite() {
            f64::INFINITY
        } else {
            0.5 * (a + b)
        }
    }
}

/// Performance ratios `r[p][s]`.
pub fn ratios(t: &[Vec<f64>]) -> Vec<Vec<f64>> {
    t.iter()
        .map(|row| {
            let best = row.iter().copied().fold(f64::INFINITY, f64::min);
            row.iter()
                .map(|&x| {
                    if best.is_finite() && x.is_finite() {
                        // A zero time (below the clock's resolution) is as good as the best.
                        if best > 0.0 {
                            x / best
                        } else if x > 0.0 {
                            f64::INFINITY
                        } else {
                            1.0
                        }
                    } else {
                        f64::INFINITY
                    }
                })
                .collect()
        })
        .collect()
}

/// The step function `rho_s` of solver `s` as corner points `(log2 tau, rho)`, from
/// `log2 tau = 0` to `x_end` (a horizontal last segment).
pub fn profile_steps(r: &[Vec<f64>], s: usize, x_end: f64) -> Vec<(f64, f64)> {
    let np = r.len().max(1) as f64;
    let mut finite: Vec<f64> = r
        .iter()
        .map(|row| row[s])
        .filter(|x| x.is_finite())
        .collect();
    finite.sort_by(|a, b| a.total_cmp(b));
    let mut pts = Vec::new();
    let mut count = finite.iter().take_while(|&&x| x <= 1.0).count();
    let mut y = count as f64 / np;
    pts.push((0.0, y));
    while count < finite.len() {
        let x = finite[count].log2();
        while count < finite.len() && finite[count].log2() <= x {
            count += 1;
        }
        pts.push((x, y));
        y = count as f64 / np;
        pts.push((x, y));
    }
    pts.push((x_end.max(pts.last().map_or(0.0, |p| p.0)), y));
    pts
}

/// Largest finite ratio (1 when there is none).
pub fn max_finite_ratio(r: &[Vec<f64>]) -> f64 {
    r.iter()
        .flatten()
        .copied()
        .filter(|x| x.is_finite())
        .fold(1.0, f64::max)
}

/// Per solver: fraction of problems solved.
pub fn solved_fraction(t: &[Vec<f64>], s: usize) -> f64 {
    if t.is_empty() {
        return f64::NAN;
    }
    t.iter().filter(|row| row[s].is_finite()).count() as f64 / t.len() as f64
}

/// Per solver: fraction of problems where it is fastest (ties count for every tied solver).
pub fn fastest_fraction(r: &[Vec<f64>], s: usize) -> f64 {
    if r.is_empty() {
        return f64::NAN;
    }
    r.iter().filter(|row| row[s] <= 1.0).count() as f64 / r.len() as f64
}

/// Median over the problems that some cadmm configuration solves of `t[p][s] / best cadmm
/// time on p` (a failure of `s` counts as infinite), with the number of such problems.
pub fn median_ratio_to_best_cadmm(t: &[Vec<f64>], is_cadmm: &[bool], s: usize) -> (f64, usize) {
    let ratios: Vec<f64> = t
        .iter()
        .filter_map(|row| {
            let best = row
                .iter()
                .zip(is_cadmm)
                .filter(|(_, &c)| c)
                .map(|(&x, _)| x)
                .fold(f64::INFINITY, f64::min);
            if !best.is_finite() {
                return None;
            }
            Some(if !row[s].is_finite() {
                f64::INFINITY
            } else if best > 0.0 {
                row[s] / best
            } else {
                1.0
            })
        })
        .collect();
    (median(&ratios), ratios.len())
}

#[cfg(test)]
mod tests {
    use super::*;
    const INF: f64 = f64::INFINITY;

    #[test]
    fn medians() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[1.0, 3.0]), 2.0);
        assert_eq!(median(&[1.0, INF, INF]), INF);
        assert_eq!(median(&[1.0, 2.0, INF]), 2.0);
        assert!(median(&[]).is_nan());
    }

    #[test]
    fn profile_of_three_problems() {
        // Problem 0: A twice as slow as B; problem 1: only A; problem 2: nobody.
        let t = vec![vec![2.0, 1.0], vec![1.0, INF], vec![INF, INF]];
        let r = ratios(&t);
        assert_eq!(r, vec![vec![2.0, 1.0], vec![1.0, INF], vec![INF, INF]]);
        assert_eq!(
            profile_steps(&r, 0, 3.0),
            vec![
                (0.0, 1.0 / 3.0),
                (1.0, 1.0 / 3.0),
                (1.0, 2.0 / 3.0),
                (3.0, 2.0 / 3.0)
            ]
        );
        assert_eq!(
            profile_steps(&r, 1, 3.0),
            vec![(0.0, 1.0 / 3.0), (3.0, 1.0 / 3.0)]
        );
        assert_eq!(max_finite_ratio(&r), 2.0);
        assert_eq!(solved_fraction(&t, 0), 2.0 / 3.0);
        assert_eq!(fastest_fraction(&r, 0), 1.0 / 3.0);
        assert_eq!(fastest_fraction(&r, 1), 1.0 / 3.0);
        // A is cadmm, B a peer: best cadmm = A on problems 0 and 1.
        let c = [true, false];
        assert_eq!(median_ratio_to_best_cadmm(&t, &c, 0), (1.0, 2));
        assert_eq!(median_ratio_to_best_cadmm(&t, &c, 1), (INF, 2));
    }
}

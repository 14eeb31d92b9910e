//! Sign-flip randomization counts for the diagnosis's one-sided tests of held-out
//! improvements, drawn from numpy's PCG64 stream so that a seed gives the p-value numpy's own
//! `Generator(seed).integers(0, 2, size=(k, n), dtype=np.int8)` signs give.
//!
//! Under the null the per-maneuver improvements `d` are symmetric about zero, so the statistic
//! `Σ s_i w_i` with random signs `s_i = ±1` has the null distribution of the observed
//! `Σ w_i` (Fisher 1935; Good 2005, Section 3.1.2). The p-value estimate is
//! `(1 + hits) / (1 + draws)` (Davison & Hinkley 1997, Eq. 4.11); the caller forms it.
//!
//! **The stream.** numpy's PCG64 is PCG-XSL-RR 128/64 (O'Neill 2014): the 128-bit LCG state
//! advances, `s ← s·M + inc`, then the output is `rotr64(hi(s) ⊕ lo(s), s >> 122)`. numpy draws
//! an `int8` in `[0, 2)` from the next byte of a buffered 32-bit output (the low half of a
//! 64-bit output first), the value being the byte's top bit (Lemire's method never rejects for
//! a range of 2), and each `integers` call starts a new 32-bit word. A draw's sign of maneuver
//! `i` is therefore the top bit of byte `i` of the draw's `n` bytes, little-endian in the
//! 64-bit outputs. `aerodelta.diagnosis.cv` checks the whole chain against numpy at first use.

/// numpy's `PCG64` bit generator, from the `state` and `inc` of
/// `Generator.bit_generator.state["state"]`.
#[derive(Debug, Clone)]
pub struct Pcg64 {
    state: u128,
    inc: u128,
}

/// PCG's default 128-bit multiplier (numpy `PCG_DEFAULT_MULTIPLIER_128`).
const MULTIPLIER: u128 = 0x2360_ED05_1FC6_5DA4_4385_DF64_9FCC_F645;

impl Pcg64 {
    /// The generator at `state` with increment `inc` (odd, as numpy keeps it).
    pub fn new(state: u128, inc: u128) -> Self {
        Pcg64 { state, inc }
    }

    /// The next 64-bit output (numpy's `random_raw`).
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_mul(MULTIPLIER).wrapping_add(self.inc);
        let s = self.state;
        (((s >> 64) as u64) ^ (s as u64)).rotate_right((s >> 122) as u32)
    }
}

/// Bytes of a [`Pcg64`] stream in order (the little-endian bytes of its outputs).
struct ByteStream {
    rng: Pcg64,
    /// Bytes of the last output not yet taken.
    left: Vec<u8>,
}

impl ByteStream {
    fn new(rng: Pcg64) -> Self {
        ByteStream {
            rng,
            left: Vec::with_capacity(8),
        }
    }

    /// The next `k` bytes into `out` (cleared first).
    fn take(&mut self, k: usize, out: &mut Vec<u8>) {
        out.clear();
        let first = self.left.len().min(k);
        out.extend(self.left.drain(..first));
        let have = out.len();
        let words = (k - have).div_ceil(8);
        out.resize(have + 8 * words, 0);
        for chunk in out[have..].chunks_exact_mut(8) {
            chunk.copy_from_slice(&self.rng.next_u64().to_le_bytes());
        }
        self.left.extend_from_slice(&out[k..]);
        out.truncate(k);
    }
}

/// The top bit of byte `j` of `word` as bit `j` of the result: the bits `8j + 7` of the
/// little-endian word shifted to `8j`, then moved to `56 + j` by one multiply.
#[inline]
fn top_bits(word: [u8; 8]) -> usize {
    let x = (u64::from_le_bytes(word) >> 7) & 0x0101_0101_0101_0101;
    (x.wrapping_mul(0x0102_0408_1020_4080) >> 56) as usize
}

/// Draws whose bytes are taken at once (bounds the buffer: `BLOCK · n` bytes).
const BLOCK: usize = 4096;

/// Options of [`flip_hits`]: numpy's call size and the tail extension.
#[derive(Debug, Clone, Copy)]
pub struct FlipOptions {
    /// Draws first made.
    pub draws: usize,
    /// Most draws per `integers` call (each call starts a new 32-bit word).
    pub per_call: usize,
    /// When fewer than `min_hits` of the first `draws` reach the statistic, draw until
    /// `draws · tail` in all (the estimate would otherwise sit at its floor `1/(draws+1)`).
    pub tail: usize,
    /// See `tail`.
    pub min_hits: u64,
}

/// Number of sign draws `s` with `Σ s_i weights_i ≥ w`, and the number of draws made, with the
/// signs of numpy's `integers(0, 2, size=(k, n), dtype=np.int8) * 2 - 1` from `rng` (module
/// doc). The sum of each group of 8 maneuvers is read from a table of its 256 sign patterns.
pub fn flip_hits(weights: &[f64], w: f64, rng: Pcg64, opts: &FlipOptions) -> (u64, u64) {
    let n = weights.len();
    let groups = n.div_ceil(8);
    // per group, the signed sum of its weights for each of the 256 patterns
    let mut table = vec![0.0f64; groups * 256];
    for g in 0..groups {
        let ws = &weights[8 * g..(8 * g + 8).min(n)];
        for pat in 0..256usize {
            table[g * 256 + pat] = ws
                .iter()
                .enumerate()
                .map(|(j, &x)| if (pat >> j) & 1 == 1 { x } else { -x })
                .sum();
        }
    }
    let mut stream = ByteStream::new(rng);
    let (mut hits, mut draws) = (0u64, 0usize);
    let mut total = opts.draws;
    let per_call = opts.per_call.max(1);
    let mut bytes = Vec::new();
    while draws < total {
        let k = per_call.min(total - draws);
        let mut done = 0;
        while done < k {
            let b = BLOCK.min(k - done);
            stream.take(b * n, &mut bytes);
            for row in bytes.chunks_exact(n.max(1)).take(b) {
                let mut s = 0.0;
                let mut groups_of_row = row.chunks_exact(8);
                for (g, chunk) in groups_of_row.by_ref().enumerate() {
                    let mut word = [0u8; 8];
                    word.copy_from_slice(chunk);
                    s += table[g * 256 + top_bits(word)];
                }
                let rest = groups_of_row.remainder();
                if !rest.is_empty() {
                    let mut word = [0u8; 8];
                    word[..rest.len()].copy_from_slice(rest);
                    s += table[(groups - 1) * 256 + top_bits(word)];
                }
                hits += u64::from(s >= w);
            }
            done += b;
        }
        // the rest of the call's last 32-bit word
        stream.take((4 - (k * n) % 4) % 4, &mut bytes);
        draws += k;
        if draws == opts.draws && hits < opts.min_hits {
            total = opts.draws * opts.tail.max(1);
        }
    }
    (hits, draws as u64)
}

/// One test of [`flip_hits_many`]: the weights, the statistic and the generator.
#[derive(Clone, Debug)]
pub struct FlipJob {
    pub weights: Vec<f64>,
    pub w: f64,
    pub rng: Pcg64,
}

/// [`flip_hits`] of each job, the jobs in parallel (each its own stream: the same counts with
/// any number of threads).
pub fn flip_hits_many(jobs: &[FlipJob], opts: &FlipOptions) -> Vec<(u64, u64)> {
    let one = |j: &FlipJob| flip_hits(&j.weights, j.w, j.rng.clone(), opts);
    #[cfg(feature = "parallel")]
    {
        use rayon::prelude::*;
        jobs.par_iter().map(one).collect()
    }
    #[cfg(not(feature = "parallel"))]
    {
        jobs.iter().map(one).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// numpy 2.4: `default_rng(12345).bit_generator` state and its first `random_raw(4)`.
    #[test]
    fn the_stream_is_numpys_pcg64() {
        let mut rng = Pcg64::new(
            0x1905_e033_5aae_9634_9199_b0d0_9775_add5,
            0xc9c7_353e_6e2b_1f28_7d76_1f2d_4027_fae7,
        );
        let want = [
            0x3a32_b18d_b2ff_c19d_u64,
            0x5117_1315_c9e4_c4de,
            0xcc20_2482_3444_efd9,
            0xad1f_06ae_a486_e910,
        ];
        for w in want {
            assert_eq!(rng.next_u64(), w);
        }
    }

    /// Against an enumeration: with few maneuvers and many draws the estimate approaches the
    /// exact tail probability of the sign-flip distribution.
    #[test]
    fn hits_estimate_the_exact_tail_probability() {
        let weights = [0.3, -1.2, 0.7, 2.0, 0.1, -0.4, 1.1, 0.9, 0.5, -0.8, 1.5];
        let n = weights.len();
        let w = 2.5;
        let exact = (0..1u32 << n)
            .filter(|pat| {
                let s: f64 = (0..n)
                    .map(|j| {
                        if (pat >> j) & 1 == 1 {
                            weights[j]
                        } else {
                            -weights[j]
                        }
                    })
                    .sum();
                s >= w
            })
            .count() as f64
            / f64::from(1u32 << n);
        let opts = FlipOptions {
            draws: 200_000,
            per_call: 50_000,
            tail: 10,
            min_hits: 20,
        };
        let (hits, draws) = flip_hits(&weights, w, Pcg64::new(7, 11), &opts);
        assert_eq!(draws, 200_000);
        let p = hits as f64 / draws as f64;
        let se = (exact * (1.0 - exact) / draws as f64).sqrt();
        assert!((p - exact).abs() < 4.0 * se, "{p} vs {exact}");
    }

    /// Fewer than `min_hits` in the first draws extends them `tail` times.
    #[test]
    fn a_far_tail_statistic_gets_the_tail_draws() {
        let weights = [1.0; 12];
        let opts = FlipOptions {
            draws: 1000,
            per_call: 300,
            tail: 10,
            min_hits: 20,
        };
        // all 12 signs positive: probability 1/4096
        let (_, draws) = flip_hits(&weights, 12.0, Pcg64::new(3, 5), &opts);
        assert_eq!(draws, 10_000);
        let (_, draws) = flip_hits(&weights, 0.0, Pcg64::new(3, 5), &opts);
        assert_eq!(draws, 1000);
    }

    #[test]
    fn many_jobs_count_as_each_alone() {
        let opts = FlipOptions {
            draws: 500,
            per_call: 200,
            tail: 3,
            min_hits: 20,
        };
        let jobs: Vec<FlipJob> = (0..5u32)
            .map(|k| FlipJob {
                weights: (1..=(9 + 4 * k)).map(f64::from).collect(),
                w: f64::from(k) * 7.0,
                rng: Pcg64::new(
                    u128::from(k) * 0x9E37_79B9_7F4A_7C15 + 1,
                    2 * u128::from(k) + 1,
                ),
            })
            .collect();
        let many = flip_hits_many(&jobs, &opts);
        for (j, got) in jobs.iter().zip(&many) {
            assert_eq!(*got, flip_hits(&j.weights, j.w, j.rng.clone(), &opts));
        }
    }
}

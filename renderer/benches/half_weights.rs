//! Would half-precision weights make the batched target net faster? The shipped kernel
//! (`TargetNet::forward_batch`, f32 weights and activations, FMA) against two variants of
//! its hidden layers on the same 6-60-60-60-60-3 net, blocked as the kernel was when this was
//! measured (6 points × 32 outputs per pass, even and odd input chains; the shipped kernel now
//! runs 6 points × 64 outputs in one chain per output, with the same 4 weight loads per 24
//! FMAs, so the conversions' share is unchanged):
//! - f16 weights converted to f32 after each load (F16C `vcvtph2ps`), f32 FMA accumulation;
//! - bf16 weights and bf16 activations multiplied in pairs with f32 accumulation
//!   (AVX512_BF16 `vdpbf16ps`, two multiply-adds per lane and instruction).
//!
//! Prints evaluations/s of each and the largest difference of the net's output y (the mapped
//! log-value) from the f32 kernel over 4,098 points. AVX-512 machines only (the variants are
//! skipped elsewhere). Run: `cargo bench -p renderer --bench half_weights`.

// Kernels index points and registers by position, as the shipped one does.
#![allow(clippy::needless_range_loop)]

use renderer::neural::mlp::{DenseLayer, Mlp};
use renderer::neural::target_net::{TargetNet, INPUTS, OUTPUTS};
use std::hint::black_box;
use std::time::Instant;

const WIDTHS: [usize; 6] = [6, 60, 60, 60, 60, 3];
/// A multiple of [`B`]: the variants have no code for a partial pass.
const POINTS: usize = 4098;
/// Points per pass and padded width (as the shipped AVX-512 kernel).
const B: usize = 6;
const STRIDE: usize = 64;

/// A deterministic net with weights of the shipped nets' scale (U(−1/√d, 1/√d)).
fn net() -> Mlp {
    let mut state = 0x9e37_79b9u32;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        (state >> 8) as f32 / (1 << 24) as f32 * 2.0 - 1.0
    };
    Mlp {
        layers: WIDTHS
            .windows(2)
            .map(|w| DenseLayer {
                d_in: w[0],
                d_out: w[1],
                weight: (0..w[0] * w[1]).map(|_| next() / (w[0] as f32).sqrt()).collect(),
                bias: (0..w[1]).map(|_| 0.1 * next()).collect(),
            })
            .collect(),
    }
}

fn inputs() -> Vec<[f32; INPUTS]> {
    (0..POINTS)
        .map(|i| std::array::from_fn(|k| ((i * 7 + k * 13) % 97) as f32 / 48.5 - 1.0))
        .collect()
}

/// Evaluations per second of `f` over [`POINTS`] points (best of 5 rounds of 50 calls).
fn rate(mut f: impl FnMut()) -> f64 {
    f();
    (0..5)
        .map(|_| {
            let start = Instant::now();
            for _ in 0..50 {
                f();
            }
            (50 * POINTS) as f64 / start.elapsed().as_secs_f64()
        })
        .fold(0.0, f64::max)
}

fn main() {
    let mlp = net();
    let xs = inputs();
    let reference = TargetNet::new(&mlp).expect("net");
    let mut want = vec![[0.0; OUTPUTS]; POINTS];
    let f32_rate = rate(|| {
        reference.forward_batch(&xs, &mut want);
        black_box(&want);
    });
    println!("f32 weights (shipped kernel, {:?}): {:.2} M evals/s", reference.kernel(), f32_rate * 1e-6);
    #[cfg(target_arch = "x86_64")]
    {
        if !std::is_x86_feature_detected!("avx512f") || !std::is_x86_feature_detected!("f16c") {
            println!("no AVX-512F/F16C here: the half-precision variants are not measured");
            return;
        }
        let packed = variants::Packed::new(&mlp);
        let mut got = vec![[0.0; OUTPUTS]; POINTS];
        let f16_rate = rate(|| {
            // SAFETY: AVX-512F and F16C were detected above.
            unsafe { packed.forward_f16(&xs, &mut got) };
            black_box(&got);
        });
        println!(
            "f16 weights, f32 FMA: {:.2} M evals/s ({:.2}x), largest |y - y_f32| {:.2e}",
            f16_rate * 1e-6,
            f16_rate / f32_rate,
            largest_difference(&got, &want)
        );
        if !std::is_x86_feature_detected!("avx512bf16") {
            println!("no AVX512_BF16 here: the bf16 variant is not measured");
            return;
        }
        let bf16_rate = rate(|| {
            // SAFETY: AVX-512F and AVX512_BF16 were detected above.
            unsafe { packed.forward_bf16(&xs, &mut got) };
            black_box(&got);
        });
        println!(
            "bf16 weights and activations, f32 accumulation (vdpbf16ps): {:.2} M evals/s ({:.2}x), largest |y - y_f32| {:.2e}",
            bf16_rate * 1e-6,
            bf16_rate / f32_rate,
            largest_difference(&got, &want)
        );
    }
}

fn largest_difference(a: &[[f32; OUTPUTS]], b: &[[f32; OUTPUTS]]) -> f32 {
    a.iter().zip(b).flat_map(|(x, y)| x.iter().zip(y).map(|(p, q)| (p - q).abs())).fold(0.0, f32::max)
}

#[cfg(target_arch = "x86_64")]
mod variants {
    use super::{bf16, B, INPUTS, OUTPUTS, STRIDE};
    use renderer::neural::mlp::Mlp;
    use std::arch::x86_64::*;

    /// A hidden layer: input width (even), f16 weights `[d_in][STRIDE]`, bf16 weights in
    /// input pairs `[d_in / 2][STRIDE][2]`, f32 bias `[STRIDE]` (zero-padded).
    type Layer = (usize, Vec<u16>, Vec<u16>, Vec<f32>);

    /// The net's layers in the two half-precision layouts.
    pub struct Packed {
        hidden: Vec<Layer>,
        /// Output layer, f32, `[OUTPUTS][STRIDE]`, and its bias.
        out: (Vec<f32>, [f32; OUTPUTS]),
    }

    impl Packed {
        pub fn new(mlp: &Mlp) -> Self {
            let (last, hidden) = mlp.layers.split_last().expect("layers");
            let hidden = hidden
                .iter()
                .map(|l| {
                    let d_in = l.d_in + l.d_in % 2;
                    let w = |i: usize, j: usize| if i < l.d_in && j < l.d_out { l.weight[i * l.d_out + j] } else { 0.0 };
                    let f16: Vec<u16> = (0..d_in * STRIDE)
                        .map(|k| ::half::f16::from_f32(w(k / STRIDE, k % STRIDE)).to_bits())
                        .collect();
                    let pairs: Vec<u16> = (0..d_in / 2 * STRIDE * 2)
                        .map(|k| bf16(w(2 * (k / (2 * STRIDE)) + k % 2, (k / 2) % STRIDE)))
                        .collect();
                    let bias = (0..STRIDE).map(|j| if j < l.d_out { l.bias[j] } else { 0.0 }).collect();
                    (d_in, f16, pairs, bias)
                })
                .collect();
            let mut out = vec![0.0; OUTPUTS * STRIDE];
            for i in 0..last.d_in {
                for c in 0..OUTPUTS {
                    out[c * STRIDE + i] = last.weight[i * OUTPUTS + c];
                }
            }
            Packed {
                hidden,
                out: (out, [last.bias[0], last.bias[1], last.bias[2]]),
            }
        }

        #[target_feature(enable = "avx512f,f16c")]
        pub unsafe fn forward_f16(&self, xs: &[[f32; INPUTS]], ys: &mut [[f32; OUTPUTS]]) {
            for (x, y) in xs.chunks_exact(B).zip(ys.chunks_exact_mut(B)) {
                let mut a = [[0f32; STRIDE]; B];
                for p in 0..B {
                    a[p][..INPUTS].copy_from_slice(&x[p]);
                }
                for (d_in, w, _, bias) in &self.hidden {
                    let mut o = [[0f32; STRIDE]; B];
                    for c in (0..STRIDE).step_by(32) {
                        let b0 = unsafe { _mm512_loadu_ps(bias.as_ptr().add(c)) };
                        let b1 = unsafe { _mm512_loadu_ps(bias.as_ptr().add(c + 16)) };
                        let mut even = [[b0, b1]; B];
                        let mut odd = [[_mm512_setzero_ps(); 2]; B];
                        for k in 0..d_in / 2 {
                            let row = |i: usize, g: usize| unsafe {
                                _mm512_cvtph_ps(_mm256_loadu_si256(w.as_ptr().add(i * STRIDE + c + 16 * g).cast()))
                            };
                            let (w00, w01, w10, w11) = (row(2 * k, 0), row(2 * k, 1), row(2 * k + 1, 0), row(2 * k + 1, 1));
                            for p in 0..B {
                                let (x0, x1) = (_mm512_set1_ps(a[p][2 * k]), _mm512_set1_ps(a[p][2 * k + 1]));
                                even[p][0] = _mm512_fmadd_ps(x0, w00, even[p][0]);
                                even[p][1] = _mm512_fmadd_ps(x0, w01, even[p][1]);
                                odd[p][0] = _mm512_fmadd_ps(x1, w10, odd[p][0]);
                                odd[p][1] = _mm512_fmadd_ps(x1, w11, odd[p][1]);
                            }
                        }
                        for p in 0..B {
                            for g in 0..2 {
                                let v = _mm512_max_ps(_mm512_add_ps(even[p][g], odd[p][g]), _mm512_setzero_ps());
                                unsafe { _mm512_storeu_ps(o[p].as_mut_ptr().add(c + 16 * g), v) };
                            }
                        }
                    }
                    a = o;
                }
                self.output(&a, y);
            }
        }

        #[target_feature(enable = "avx512f,avx512bf16")]
        pub unsafe fn forward_bf16(&self, xs: &[[f32; INPUTS]], ys: &mut [[f32; OUTPUTS]]) {
            for (x, y) in xs.chunks_exact(B).zip(ys.chunks_exact_mut(B)) {
                let mut a = [[0f32; STRIDE]; B];
                for p in 0..B {
                    a[p][..INPUTS].copy_from_slice(&x[p]);
                }
                for (d_in, _, w, bias) in &self.hidden {
                    // Activations as bf16 pairs, one 32-bit word per input pair.
                    let mut pairs = [[0u32; STRIDE / 2]; B];
                    for (pair, act) in pairs.iter_mut().zip(&a) {
                        for (k, word) in pair.iter_mut().take(d_in / 2).enumerate() {
                            *word = bf16(act[2 * k]) as u32 | (bf16(act[2 * k + 1]) as u32) << 16;
                        }
                    }
                    let mut o = [[0f32; STRIDE]; B];
                    for c in (0..STRIDE).step_by(32) {
                        let b0 = unsafe { _mm512_loadu_ps(bias.as_ptr().add(c)) };
                        let b1 = unsafe { _mm512_loadu_ps(bias.as_ptr().add(c + 16)) };
                        let mut acc = [[b0, b1]; B];
                        for k in 0..d_in / 2 {
                            // SAFETY: 32 bf16 values of row pair k inside `w`; __m512bh is
                            // 512 bits like __m512i.
                            let load = |g: usize| unsafe {
                                std::mem::transmute::<__m512i, __m512bh>(_mm512_loadu_si512(
                                    w.as_ptr().add((k * STRIDE + c + 16 * g) * 2).cast(),
                                ))
                            };
                            let (w0, w1) = (load(0), load(1));
                            for p in 0..B {
                                // SAFETY: as above.
                                let x = unsafe { std::mem::transmute::<__m512i, __m512bh>(_mm512_set1_epi32(pairs[p][k] as i32)) };
                                acc[p][0] = _mm512_dpbf16_ps(acc[p][0], x, w0);
                                acc[p][1] = _mm512_dpbf16_ps(acc[p][1], x, w1);
                            }
                        }
                        for p in 0..B {
                            for g in 0..2 {
                                let v = _mm512_max_ps(acc[p][g], _mm512_setzero_ps());
                                unsafe { _mm512_storeu_ps(o[p].as_mut_ptr().add(c + 16 * g), v) };
                            }
                        }
                    }
                    a = o;
                }
                self.output(&a, y);
            }
        }

        fn output(&self, a: &[[f32; STRIDE]; B], y: &mut [[f32; OUTPUTS]]) {
            for p in 0..B {
                for c in 0..OUTPUTS {
                    y[p][c] = self.out.1[c] + a[p].iter().zip(&self.out.0[c * STRIDE..]).map(|(u, v)| u * v).sum::<f32>();
                }
            }
        }
    }
}

/// `v` rounded to the nearest bf16 (ties to even; no NaNs here), as its bits.
fn bf16(v: f32) -> u16 {
    let b = v.to_bits();
    ((b + 0x7fff + ((b >> 16) & 1)) >> 16) as u16
}

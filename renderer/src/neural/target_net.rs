//! A decoded FreNBRDF target net — the per-material MLP the hypernetwork generates from a
//! latent code — packed for fast f32 evaluation on the CPU.
//!
//! The net maps the 6D input of [`crate::brdf_coords::network_input`] to the mapped value y
//! per RGB channel: ReLU after every hidden layer, a linear output layer. Layout: every hidden
//! layer's output width is padded to a multiple of [`Kernel::stride_multiple`] lanes (64 for
//! AVX-512, 8 otherwise) with zero weights and biases, so the padded activations are 0 after
//! ReLU and never contribute; its weights are
//! stored `[d_in][stride]` row-major. The output layer (3 channels) is stored transposed,
//! `[3][stride]`, and evaluated as dot products.
//!
//! Kernels, chosen once per net from the CPU's features: AVX-512F (16 lanes per register),
//! AVX2 + FMA (8 lanes), and a portable loop. Every hidden output is one chain of FMAs from
//! its bias over the inputs in order, whatever the number of points, so a point's output is
//! the same bits alone and in a batch (what keeps batched rendering equal to one path at a
//! time). One point keeps up to 64 outputs in flight (eight independent chains on AVX2,
//! enough to hide the FMA latency); a batch runs several points over fewer registers each
//! (six points × two registers on AVX2, × four on AVX-512; a width that is not a multiple
//! ends in smaller blocks), so that every
//! weight load is shared by six points' accumulators and the kernel runs close to the FMA
//! throughput. The vector kernels skip the weight rows of inputs that are zero in every point
//! of a pass (ReLU leaves 40–77 % of a decoded net's hidden activations at zero), which
//! changes no bit of the result; a batch is run in order of sin θh, so that the points of a
//! pass share more of their zeros.

use crate::neural::mlp::Mlp;
use crate::{Error, Result};

/// Input width of the target net.
pub const INPUTS: usize = 6;
/// Output width (RGB).
pub const OUTPUTS: usize = 3;
/// Widest hidden layer the evaluator supports (activations live on the stack).
pub const MAX_WIDTH: usize = 256;

/// The forward-pass implementation in use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// 512-bit vectors (x86-64 with AVX-512F).
    Avx512,
    /// 256-bit vectors with fused multiply-add (x86-64 with AVX2 and FMA).
    Avx2Fma,
    /// Plain loops, any CPU.
    Portable,
}

impl Kernel {
    /// Hidden widths are padded to a multiple of this many outputs: the AVX-512 kernel's
    /// block (four registers of 16), one register of eight for the others (whose kernels
    /// end a width with smaller blocks). The padding's outputs are computed and are zero.
    pub fn stride_multiple(self) -> usize {
        match self {
            Kernel::Avx512 => 64,
            Kernel::Avx2Fma | Kernel::Portable => 8,
        }
    }

    /// The fastest kernel this CPU runs.
    pub fn detect() -> Self {
        use crate::support::cpu::{has_avx2_fma, has_avx512f};
        #[cfg(target_arch = "x86_64")]
        {
            if has_avx512f() {
                return Kernel::Avx512;
            }
            if has_avx2_fma() {
                return Kernel::Avx2Fma;
            }
        }
        Kernel::Portable
    }
}

/// A hidden layer: relu(x · W + b), padded.
#[derive(Clone, Debug)]
struct HiddenLayer {
    /// Real input width (the padded inputs beyond it are zero and skipped).
    d_in: usize,
    /// Padded output width, a multiple of the kernel's [`Kernel::stride_multiple`].
    stride: usize,
    /// W, `[d_in][stride]` row-major, zero beyond the real output width.
    weight: Vec<f32>,
    /// b, `[stride]`, zero beyond the real output width.
    bias: Vec<f32>,
}

/// A target net ready for evaluation.
#[derive(Clone, Debug)]
pub struct TargetNet {
    hidden: Vec<HiddenLayer>,
    /// Output layer transposed, `[OUTPUTS][stride of the last hidden layer]`.
    out_weight: Vec<f32>,
    out_bias: [f32; OUTPUTS],
    /// Multiply-adds of one evaluation at the real (unpadded) widths.
    macs: usize,
    kernel: Kernel,
}

/// Activations of one point, hidden widths padded (64-byte aligned for the vector loads).
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Activations([f32; MAX_WIDTH]);

impl Activations {
    const ZERO: Self = Activations([0.0; MAX_WIDTH]);
}

impl TargetNet {
    /// Bytes of its weights and biases as packed (padding included).
    pub fn heap_bytes(&self) -> usize {
        let floats: usize = self.hidden.iter().map(|l| l.weight.len() + l.bias.len()).sum::<usize>() + self.out_weight.len();
        floats * std::mem::size_of::<f32>()
    }

    /// Packs a decoded MLP (see [`crate::formats::latent_file::LatentFile::decode`]) for the fastest
    /// kernel of this CPU. Errors unless it maps [`INPUTS`] to [`OUTPUTS`] values through at
    /// least one hidden layer no wider than [`MAX_WIDTH`], with finite weights.
    pub fn new(mlp: &Mlp) -> Result<Self> {
        Self::with_kernel(mlp, Kernel::detect())
    }

    /// As [`TargetNet::new`] with a chosen kernel; a kernel the CPU lacks falls back to the
    /// portable one.
    pub fn with_kernel(mlp: &Mlp, kernel: Kernel) -> Result<Self> {
        let invalid = |reason: String| Error::InvalidArgument {
            flag: "target net".to_string(),
            reason,
        };
        let layers = &mlp.layers;
        let widths: Vec<usize> = layers.iter().map(|l| l.d_in).chain(layers.last().map(|l| l.d_out)).collect();
        if layers.len() < 2 || widths[0] != INPUTS || widths[widths.len() - 1] != OUTPUTS {
            return Err(invalid(format!(
                "widths {widths:?}: expected {INPUTS} inputs, hidden layers and {OUTPUTS} outputs"
            )));
        }
        if let Some(w) = widths[1..widths.len() - 1].iter().find(|&&w| w > MAX_WIDTH) {
            return Err(invalid(format!("hidden width {w} exceeds {MAX_WIDTH}")));
        }
        for (k, layer) in layers.iter().enumerate() {
            if layer.weight.len() != layer.d_in * layer.d_out
                || layer.bias.len() != layer.d_out
                || (k > 0 && layer.d_in != layers[k - 1].d_out)
            {
                return Err(invalid(format!("layer {k} has inconsistent shapes")));
            }
            if layer.weight.iter().chain(&layer.bias).any(|v| !v.is_finite()) {
                return Err(invalid(format!("layer {k} has non-finite weights")));
            }
        }
        let kernel = if kernel == Kernel::Portable || Kernel::detect() == Kernel::Portable {
            Kernel::Portable
        } else if kernel == Kernel::Avx512 && Kernel::detect() != Kernel::Avx512 {
            Kernel::Avx2Fma
        } else {
            kernel
        };
        let (output, hidden_layers) = layers.split_last().expect("at least two layers");
        let hidden: Vec<HiddenLayer> = hidden_layers
            .iter()
            .map(|l| {
                let stride = l.d_out.next_multiple_of(kernel.stride_multiple());
                let mut weight = vec![0.0; l.d_in * stride];
                for (row, src) in weight.chunks_exact_mut(stride).zip(l.weight.chunks_exact(l.d_out)) {
                    row[..l.d_out].copy_from_slice(src);
                }
                let mut bias = vec![0.0; stride];
                bias[..l.d_out].copy_from_slice(&l.bias);
                HiddenLayer {
                    d_in: l.d_in,
                    stride,
                    weight,
                    bias,
                }
            })
            .collect();
        let last_stride = hidden.last().expect("a hidden layer").stride;
        let mut out_weight = vec![0.0; OUTPUTS * last_stride];
        for i in 0..output.d_in {
            for c in 0..OUTPUTS {
                out_weight[c * last_stride + i] = output.weight[i * OUTPUTS + c];
            }
        }
        Ok(TargetNet {
            hidden,
            out_weight,
            out_bias: [output.bias[0], output.bias[1], output.bias[2]],
            macs: layers.iter().map(|l| l.d_in * l.d_out).sum(),
            kernel,
        })
    }

    /// The kernel in use.
    pub fn kernel(&self) -> Kernel {
        self.kernel
    }

    /// Floating-point operations of one evaluation at the real widths (a multiply-add counts
    /// two), the figure throughput is measured against.
    pub fn flops_per_eval(&self) -> usize {
        2 * self.macs
    }

    /// The output y for one input.
    #[inline]
    pub fn forward(&self, x: [f32; INPUTS]) -> [f32; OUTPUTS] {
        let mut out = [[0.0; OUTPUTS]];
        let mut scratch = [[Activations::ZERO; 1]; 2];
        match self.kernel {
            Kernel::Avx512 => self.forward_points::<1, { ONE_POINT_AVX512 }>(&[x], &mut out, &mut scratch),
            Kernel::Avx2Fma => self.forward_points::<1, { ONE_POINT_AVX2 }>(&[x], &mut out, &mut scratch),
            Kernel::Portable => self.forward_points::<1, 1>(&[x], &mut out, &mut scratch),
        }
        out[0]
    }

    /// The outputs for many inputs (`outputs.len()` must equal `inputs.len()`), several points
    /// per pass of the kernel ([`TargetNet::batch_size`]). Each output is bit for bit what
    /// [`TargetNet::forward`] gives for its input.
    ///
    /// The points are run in order of their first input, sin θh, up to [`ORDERED`] at a time
    /// (and the outputs put back in the callers' order): neighbours in θh switch off mostly
    /// the same hidden units, so the rows a pass skips — those zero in all of its points —
    /// are more (a quarter fewer rows evaluated in the material-preview render), and what a
    /// point gives does not depend on its neighbours.
    pub fn forward_batch(&self, inputs: &[[f32; INPUTS]], outputs: &mut [[f32; OUTPUTS]]) {
        assert_eq!(inputs.len(), outputs.len(), "one output per input");
        self.forward_each(inputs.len(), |i| inputs[i], |i, y| outputs[i] = y);
    }

    /// [`TargetNet::forward_batch`] of `count` points whose inputs `input(i)` gives, each
    /// output handed to `output(i, y)` (in the order the passes run): for callers whose
    /// inputs and outputs live in their own records, without copying them to arrays and back.
    #[inline]
    pub fn forward_each(&self, count: usize, input: impl Fn(usize) -> [f32; INPUTS], output: impl FnMut(usize, [f32; OUTPUTS])) {
        match self.kernel {
            Kernel::Avx512 => self.forward_ordered::<BATCH_AVX512, { BATCH_REGISTERS_AVX512 }>(count, input, output),
            Kernel::Avx2Fma => self.forward_ordered::<BATCH_AVX2, { BATCH_REGISTERS_AVX2 }>(count, input, output),
            Kernel::Portable => self.forward_ordered::<4, 1>(count, input, output),
        }
    }

    /// Points per pass of [`TargetNet::forward_batch`] with this net's kernel.
    pub fn batch_size(&self) -> usize {
        match self.kernel {
            Kernel::Avx512 => BATCH_AVX512,
            Kernel::Avx2Fma => BATCH_AVX2,
            Kernel::Portable => 4,
        }
    }

    /// [`TargetNet::forward_batch`] `B` points at a time in order of their first input, `R`
    /// registers of outputs per pass. The last pass of each ordered run is padded with
    /// copies of its last point: one more pass of the batched kernel costs less than the
    /// points one by one, and gives the same bits.
    fn forward_ordered<const B: usize, const R: usize>(
        &self,
        count: usize,
        input: impl Fn(usize) -> [f32; INPUTS],
        mut output: impl FnMut(usize, [f32; OUTPUTS]),
    ) {
        let mut scratch = [[Activations::ZERO; B]; 2];
        // A point's sort key in the high half (its first input in IEEE total order), its
        // index in the run in the low half.
        let mut keys = [0u64; ORDERED];
        for start in (0..count).step_by(ORDERED) {
            let keys = &mut keys[..ORDERED.min(count - start)];
            for (k, key) in keys.iter_mut().enumerate() {
                let bits = input(start + k)[0].to_bits();
                let ordered = if bits >> 31 == 1 { !bits } else { bits | 1 << 31 };
                *key = u64::from(ordered) << 32 | k as u64;
            }
            keys.sort_unstable();
            let index = |key: u64| start + key as u32 as usize;
            for pass in keys.chunks(B) {
                let last = index(pass[pass.len() - 1]);
                let x: [[f32; INPUTS]; B] = std::array::from_fn(|k| input(pass.get(k).map_or(last, |&key| index(key))));
                let mut y = [[0.0; OUTPUTS]; B];
                self.forward_points::<B, R>(&x, &mut y, &mut scratch);
                for (&key, y) in pass.iter().zip(&y) {
                    output(index(key), *y);
                }
            }
        }
    }

    /// The forward pass of `B` points through the selected kernel, `R` vector registers of
    /// outputs per point at a time; `scratch` holds the activations (any contents).
    #[inline]
    fn forward_points<const B: usize, const R: usize>(
        &self,
        x: &[[f32; INPUTS]; B],
        y: &mut [[f32; OUTPUTS]; B],
        scratch: &mut [[Activations; B]; 2],
    ) {
        let [mut a, mut b] = scratch.each_mut();
        for (act, xi) in a.iter_mut().zip(x) {
            act.0[..INPUTS].copy_from_slice(xi);
        }
        for layer in &self.hidden {
            match self.kernel {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: the kernel is Avx512 only when the CPU reported AVX-512F.
                Kernel::Avx512 => unsafe { simd::hidden_avx512::<B, R>(layer, a, b) },
                #[cfg(target_arch = "x86_64")]
                // SAFETY: the kernel is Avx2Fma only when the CPU reported AVX2 and FMA.
                Kernel::Avx2Fma => unsafe { simd::hidden_avx2::<B, R>(layer, a, b) },
                _ => hidden_portable(layer, a, b),
            }
            std::mem::swap(&mut a, &mut b);
        }
        let stride = self.hidden.last().expect("a hidden layer").stride;
        match self.kernel {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as above.
            Kernel::Avx512 => unsafe { simd::output_avx512::<B>(&self.out_weight, &self.out_bias, stride, a, y) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as above.
            Kernel::Avx2Fma => unsafe { simd::output_avx2::<B>(&self.out_weight, &self.out_bias, stride, a, y) },
            _ => {
                for (act, out) in a.iter().zip(y.iter_mut()) {
                    for (c, o) in out.iter_mut().enumerate() {
                        let w = &self.out_weight[c * stride..(c + 1) * stride];
                        *o = self.out_bias[c] + dot(&act.0[..stride], w);
                    }
                }
            }
        }
    }
}

/// Points [`TargetNet::forward_batch`] orders together: a step's chunk of vertices gives up to
/// this many (a light sample and a BSDF sample each).
pub const ORDERED: usize = 512;

/// Output registers per pass of the one-point kernels: the whole padded width of 64 outputs
/// in flight, eight independent FMA chains on AVX2 (enough to hide the FMA latency), four on
/// AVX-512.
const ONE_POINT_AVX2: usize = 8;
const ONE_POINT_AVX512: usize = 4;
/// Points and output registers per pass of the batched AVX-512 kernel: 6 points × 4 registers
/// = 24 accumulators, 4 weight registers and a broadcast of the 32; each weight load serves
/// six points, each broadcast four registers.
const BATCH_AVX512: usize = 6;
const BATCH_REGISTERS_AVX512: usize = 4;
/// Points and output registers per pass of the batched AVX2 kernel (16 registers): 6 × 2 = 12
/// accumulators, 2 weight registers and a broadcast; 8 loads per 12 FMAs.
const BATCH_AVX2: usize = 6;
const BATCH_REGISTERS_AVX2: usize = 2;

/// Dot product with eight partial sums (vectorises on every target).
#[inline]
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0f32; 8];
    for (ca, cb) in a.chunks_exact(8).zip(b.chunks_exact(8)) {
        for k in 0..8 {
            acc[k] += ca[k] * cb[k];
        }
    }
    acc.iter().sum()
}

/// One hidden layer of `B` points, portable.
fn hidden_portable<const B: usize>(layer: &HiddenLayer, input: &[Activations; B], output: &mut [Activations; B]) {
    let s = layer.stride;
    for (inp, out) in input.iter().zip(output.iter_mut()) {
        let out = &mut out.0[..s];
        out.copy_from_slice(&layer.bias);
        for (xi, row) in inp.0[..layer.d_in].iter().zip(layer.weight.chunks_exact(s)) {
            for (o, w) in out.iter_mut().zip(row) {
                *o += xi * w;
            }
        }
        out.iter_mut().for_each(|v| *v = v.max(0.0));
    }
}

/// The vector kernels: one macro body instantiated for 512- and 256-bit registers.
///
/// Every kernel computes each output in one order, whatever the number of points: a hidden
/// output is a chain of FMAs from its bias over the inputs in order; an output of the last
/// layer is a product of the first activation register, a chain of FMAs over the others and a
/// fixed horizontal sum. So a point gives the same bits alone as in a batch.
#[cfg(target_arch = "x86_64")]
mod simd {
    use super::{Activations, HiddenLayer, MAX_WIDTH, OUTPUTS};
    use std::arch::x86_64::*;

    macro_rules! kernels {
        ($hidden:ident, $output:ident, $feature:literal, $vec:ty, $lanes:expr, $load:ident, $store:ident,
         $set1:ident, $fmadd:ident, $mul:ident, $max:ident, $zero:ident, $hsum:path) => {
            /// One hidden layer of `B` points: relu(x · W + b) over the padded width, `R`
            /// registers of outputs at a time (`R` a power of two); a width that is not a
            /// multiple of `R` registers ends in blocks of `R/2`, `R/4`, … registers (the
            /// stride must be a multiple of one register).
            #[target_feature(enable = $feature)]
            pub(super) unsafe fn $hidden<const B: usize, const R: usize>(
                layer: &HiddenLayer,
                input: &[Activations; B],
                output: &mut [Activations; B],
            ) {
                let s = layer.stride;
                assert!(
                    R.is_power_of_two()
                        && layer.d_in <= MAX_WIDTH
                        && s <= MAX_WIDTH
                        && s % $lanes == 0
                        && layer.weight.len() >= layer.d_in * s
                        && layer.bias.len() >= s
                );
                let mut nonzero = [0u16; MAX_WIDTH];
                // SAFETY: AVX-512F and AVX2 + FMA CPUs have AVX2.
                let rows = unsafe { nonzero_inputs(input, layer.d_in, &mut nonzero) };
                let rows = &nonzero[..rows];
                let mut c = 0;
                while c + R * $lanes <= s {
                    // SAFETY: c + R·lanes ≤ stride, checked with the layer's sizes above.
                    unsafe { block::<B, R>(layer, rows, input, output, c) };
                    c += R * $lanes;
                }
                // SAFETY (the tail): each block ends at or before the stride.
                if R > 4 && c + 4 * $lanes <= s {
                    unsafe { block::<B, 4>(layer, rows, input, output, c) };
                    c += 4 * $lanes;
                }
                if R > 2 && c + 2 * $lanes <= s {
                    unsafe { block::<B, 2>(layer, rows, input, output, c) };
                    c += 2 * $lanes;
                }
                if R > 1 && c + $lanes <= s {
                    unsafe { block::<B, 1>(layer, rows, input, output, c) };
                    c += $lanes;
                }
                debug_assert_eq!(c, s);

                /// Outputs `c .. c + RR·lanes` of every point: each a chain of FMAs from
                /// its bias over the nonzero inputs `rows` in order, then ReLU.
                ///
                /// # Safety
                /// The CPU has the kernel's features; c + RR·lanes ≤ stride ≤ MAX_WIDTH and
                /// the layer holds `d_in` rows of `stride` weights and `stride` biases.
                #[target_feature(enable = $feature)]
                #[inline]
                unsafe fn block<const B: usize, const RR: usize>(
                    layer: &HiddenLayer,
                    rows: &[u16],
                    input: &[Activations; B],
                    output: &mut [Activations; B],
                    c: usize,
                ) {
                    let (s, w) = (layer.stride, layer.weight.as_ptr());
                    // SAFETY (all loads and stores below): the function's contract; rows
                    // i < d_in.
                    let mut bias: [$vec; RR] = [$zero(); RR];
                    for g in 0..RR {
                        bias[g] = unsafe { $load(layer.bias.as_ptr().add(c + g * $lanes)) };
                    }
                    let mut acc = [bias; B];
                    for &i in rows {
                        let i = usize::from(i);
                        let row = unsafe { w.add(i * s + c) };
                        let mut wi: [$vec; RR] = [$zero(); RR];
                        for g in 0..RR {
                            wi[g] = unsafe { $load(row.add(g * $lanes)) };
                        }
                        for p in 0..B {
                            let x = $set1(input[p].0[i]);
                            for g in 0..RR {
                                acc[p][g] = $fmadd(x, wi[g], acc[p][g]);
                            }
                        }
                    }
                    for p in 0..B {
                        for g in 0..RR {
                            let v = $max(acc[p][g], $zero());
                            unsafe { $store(output[p].0.as_mut_ptr().add(c + g * $lanes), v) };
                        }
                    }
                }
            }

            /// The linear output layer of `B` points: `weight` is `[OUTPUTS][stride]`. Two
            /// points at a time, so that six dot products are in flight.
            #[target_feature(enable = $feature)]
            pub(super) unsafe fn $output<const B: usize>(
                weight: &[f32],
                bias: &[f32; OUTPUTS],
                stride: usize,
                input: &[Activations; B],
                output: &mut [[f32; OUTPUTS]; B],
            ) {
                assert!(weight.len() >= OUTPUTS * stride && stride % $lanes == 0 && stride > 0 && stride <= MAX_WIDTH);
                for (points, outs) in input.chunks(2).zip(output.chunks_mut(2)) {
                    let n = points.len();
                    // SAFETY: rows of `stride` floats, checked above; stride ≤ MAX_WIDTH.
                    let row = |c: usize, g: usize| unsafe { $load(weight.as_ptr().add(c * stride + g)) };
                    let x = |q: usize, g: usize| unsafe { $load(points[q.min(n - 1)].0.as_ptr().add(g)) };
                    let mut acc = [[$zero(); OUTPUTS]; 2];
                    for q in 0..2 {
                        for c in 0..OUTPUTS {
                            acc[q][c] = $mul(x(q, 0), row(c, 0));
                        }
                    }
                    for g in (($lanes)..stride).step_by($lanes) {
                        for q in 0..2 {
                            let xg = x(q, g);
                            for c in 0..OUTPUTS {
                                acc[q][c] = $fmadd(xg, row(c, g), acc[q][c]);
                            }
                        }
                    }
                    for (out, sums) in outs.iter_mut().zip(&acc) {
                        for c in 0..OUTPUTS {
                            out[c] = bias[c] + unsafe { $hsum(sums[c]) };
                        }
                    }
                }
            }
        };
    }

    /// Writes to `rows` the indices below `d_in` of the inputs that are not zero (of either
    /// sign) in at least one of the points, in order, and returns how many there are. The
    /// kernels skip the other inputs' weight rows: an input that is zero in every point adds
    /// only zeros to every output, which can change no more than the sign of a zero sum, and
    /// ReLU's `max(sum, +0)` returns +0 for either sign, so the activations are the same bits
    /// with the rows skipped as without (and a point's the same alone as in a batch, which
    /// skips fewer). Most rows go: 40–77 % of a decoded net's hidden activations are zero,
    /// up to a third of its neurons over the whole domain.
    #[target_feature(enable = "avx2")]
    unsafe fn nonzero_inputs<const B: usize>(input: &[Activations; B], d_in: usize, rows: &mut [u16; MAX_WIDTH]) -> usize {
        let magnitude = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff));
        let d_in = d_in.min(MAX_WIDTH);
        let mut n = 0;
        for base in (0..d_in).step_by(8) {
            let mut any = _mm256_setzero_ps();
            for point in input {
                // SAFETY: base + 8 ≤ MAX_WIDTH (base is a multiple of 8 below d_in ≤ MAX_WIDTH).
                any = _mm256_or_ps(any, unsafe { _mm256_loadu_ps(point.0.as_ptr().add(base)) });
            }
            let nonzero = _mm256_cmp_ps::<_CMP_NEQ_UQ>(_mm256_and_ps(any, magnitude), _mm256_setzero_ps());
            // Lanes at or beyond d_in hold whatever an earlier layer left there.
            let mut mask = (_mm256_movemask_ps(nonzero) as u32) & (u32::MAX >> (32 - (d_in - base).min(8)));
            while mask != 0 {
                rows[n] = (base + mask.trailing_zeros() as usize) as u16;
                n += 1;
                mask &= mask - 1;
            }
        }
        n
    }

    /// Sum of the lanes of a 512-bit register (a fixed tree of additions).
    #[target_feature(enable = "avx512f")]
    unsafe fn hsum512(v: __m512) -> f32 {
        _mm512_reduce_add_ps(v)
    }

    /// Sum of the lanes of a 256-bit register (a fixed tree of additions).
    #[target_feature(enable = "avx2,fma")]
    unsafe fn hsum256(v: __m256) -> f32 {
        let quad = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps::<1>(v));
        let pair = _mm_add_ps(quad, _mm_movehl_ps(quad, quad));
        _mm_cvtss_f32(_mm_add_ss(pair, _mm_shuffle_ps::<0b01>(pair, pair)))
    }

    kernels!(hidden_avx512, output_avx512, "avx512f", __m512, 16, _mm512_loadu_ps, _mm512_storeu_ps,
        _mm512_set1_ps, _mm512_fmadd_ps, _mm512_mul_ps, _mm512_max_ps, _mm512_setzero_ps, hsum512);
    kernels!(hidden_avx2, output_avx2, "avx2,fma", __m256, 8, _mm256_loadu_ps, _mm256_storeu_ps,
        _mm256_set1_ps, _mm256_fmadd_ps, _mm256_mul_ps, _mm256_max_ps, _mm256_setzero_ps, hsum256);
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::neural::mlp::DenseLayer;
    use rand::{Rng, SeedableRng};

    /// A random MLP of the given widths (weights ~ U(−s, s) with s = 1/√d_in).
    pub(crate) fn random_mlp(widths: &[usize], seed: u64) -> Mlp {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(seed);
        Mlp {
            layers: widths
                .windows(2)
                .map(|w| {
                    let s = 1.0 / (w[0] as f32).sqrt();
                    DenseLayer {
                        d_in: w[0],
                        d_out: w[1],
                        weight: (0..w[0] * w[1]).map(|_| rng.random_range(-s..s)).collect(),
                        bias: (0..w[1]).map(|_| rng.random_range(-0.1..0.1)).collect(),
                    }
                })
                .collect(),
        }
    }

    fn random_inputs(n: usize) -> Vec<[f32; INPUTS]> {
        let mut rng = rand_pcg::Pcg32::seed_from_u64(9);
        (0..n).map(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0))).collect()
    }

    #[test]
    fn every_kernel_matches_the_reference_mlp() {
        for widths in [&[6, 60, 60, 60, 60, 3][..], &[6, 7, 3], &[6, 130, 65, 3]] {
            let mlp = random_mlp(widths, 3);
            for kernel in [Kernel::Avx512, Kernel::Avx2Fma, Kernel::Portable] {
                let net = TargetNet::with_kernel(&mlp, kernel).unwrap();
                let inputs = random_inputs(11);
                let mut batch = vec![[0.0; OUTPUTS]; inputs.len()];
                net.forward_batch(&inputs, &mut batch);
                for (x, yb) in inputs.iter().zip(&batch) {
                    let want = mlp.forward(x);
                    let y = net.forward(*x);
                    for c in 0..OUTPUTS {
                        let tol = 1e-5 * (1.0 + want[c].abs());
                        assert!((y[c] - want[c]).abs() < tol, "{kernel:?} {widths:?}: {y:?} vs {want:?}");
                        assert!((yb[c] - want[c]).abs() < tol, "{kernel:?} batch: {yb:?} vs {want:?}");
                    }
                }
            }
        }
    }

    /// Batched rendering must equal one path at a time: a point's output is the same bits
    /// in a batch as alone, for every kernel, odd and even widths, full batches and the rest,
    /// in one ordered run and over several (each output back in its input's place).
    #[test]
    fn batches_equal_single_points_bit_for_bit() {
        for widths in [&[6, 60, 60, 60, 60, 3][..], &[6, 65, 33, 3], &[6, 7, 3]] {
            let mlp = random_mlp(widths, 5);
            for kernel in [Kernel::Avx512, Kernel::Avx2Fma, Kernel::Portable] {
                let net = TargetNet::with_kernel(&mlp, kernel).unwrap();
                let inputs = random_inputs(ORDERED + 4 * net.batch_size() + 3);
                let mut batch = vec![[0.0; OUTPUTS]; inputs.len()];
                net.forward_batch(&inputs, &mut batch);
                for (x, yb) in inputs.iter().zip(&batch) {
                    let y = net.forward(*x);
                    assert_eq!(y.map(f32::to_bits), yb.map(f32::to_bits), "{kernel:?} {widths:?}");
                }
            }
        }
    }

    /// Skipping the weight rows of inputs that are zero in every point changes no bit: the
    /// AVX2 kernels, one point and batched, against the same order of operations over every
    /// input in scalar code, on inputs with exact zeros of both signs and a net whose hidden
    /// layer has dead units (a third of them never active).
    #[test]
    fn skipped_zero_rows_change_no_bits() {
        let mut mlp = random_mlp(&[6, 60, 60, 3], 7);
        mlp.layers[0].bias[..20].fill(-10.0);
        let net = TargetNet::with_kernel(&mlp, Kernel::Avx2Fma).unwrap();
        if net.kernel() != Kernel::Avx2Fma {
            return;
        }
        let mut inputs = random_inputs(64);
        for (k, x) in inputs.iter_mut().enumerate() {
            x[1] = if k % 2 == 0 { 0.0 } else { -0.0 };
            if k % 3 == 0 {
                x[4] = -0.0;
            }
        }
        let mut batch = vec![[0.0; OUTPUTS]; inputs.len()];
        net.forward_batch(&inputs, &mut batch);
        for (x, yb) in inputs.iter().zip(&batch) {
            let want = avx2_order_over_every_input(&mlp, x).map(f32::to_bits);
            assert_eq!(net.forward(*x).map(f32::to_bits), want, "one point at {x:?}");
            assert_eq!(yb.map(f32::to_bits), want, "batch at {x:?}");
        }
    }

    /// The AVX2 kernels' operations in their order, in scalar code, with no input skipped:
    /// each hidden output a chain of FMAs from its bias then `max(·, +0)`; each output an
    /// eight-lane chain over the padded activations, summed as `hsum256` does, plus the bias.
    fn avx2_order_over_every_input(mlp: &Mlp, x: &[f32; INPUTS]) -> [f32; OUTPUTS] {
        let (output, hidden) = mlp.layers.split_last().unwrap();
        let mut h = x.to_vec();
        for layer in hidden {
            h = (0..layer.d_out)
                .map(|j| {
                    let sum = (0..layer.d_in).fold(layer.bias[j], |acc, i| h[i].mul_add(layer.weight[i * layer.d_out + j], acc));
                    if sum > 0.0 { sum } else { 0.0 }
                })
                .collect();
        }
        let stride = h.len().next_multiple_of(Kernel::Avx2Fma.stride_multiple());
        h.resize(stride, 0.0);
        std::array::from_fn(|c| {
            let w = |i: usize| if i < output.d_in { output.weight[i * OUTPUTS + c] } else { 0.0 };
            let mut acc: [f32; 8] = std::array::from_fn(|j| h[j] * w(j));
            for g in (8..stride).step_by(8) {
                for (j, a) in acc.iter_mut().enumerate() {
                    *a = h[g + j].mul_add(w(g + j), *a);
                }
            }
            let quad: [f32; 4] = std::array::from_fn(|k| acc[k] + acc[k + 4]);
            output.bias[c] + ((quad[0] + quad[2]) + (quad[1] + quad[3]))
        })
    }

    #[test]
    fn flop_count_uses_real_widths() {
        let net = TargetNet::new(&random_mlp(&[6, 60, 60, 60, 60, 3], 1)).unwrap();
        assert_eq!(net.flops_per_eval(), 2 * (6 * 60 + 3 * 60 * 60 + 60 * 3));
    }

    #[test]
    fn rejects_unusable_shapes_and_values() {
        for widths in [&[6, 3][..], &[5, 8, 3], &[6, 8, 4], &[6, 300, 3]] {
            let err = TargetNet::new(&random_mlp(widths, 1)).unwrap_err().to_string();
            assert!(err.contains("target net"), "{err}");
        }
        let mut mlp = random_mlp(&[6, 8, 3], 1);
        mlp.layers[1].bias[2] = f32::NAN;
        assert!(TargetNet::new(&mlp).unwrap_err().to_string().contains("non-finite"));
    }
}

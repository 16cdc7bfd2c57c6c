//! The reference f32 forward passes of the trained model stored in a latent file: dense
//! layers, the hypernetwork heads that decode a latent code into a target net, and the set
//! encoder, and the pruning of units no input of a domain switches on
//! ([`Mlp::without_never_active_units`]). (The target net is evaluated fast by
//! [`super::target_net::TargetNet`].)
//!
//! Dense layers compute y = x · W + b with W stored [d_in, d_out] row-major (as NBRDF's `.npy`
//! tensors and burn's `Linear`).

/// One dense layer y = x · W + b.
#[derive(Clone, Debug, PartialEq)]
pub struct DenseLayer {
    /// Input width.
    pub d_in: usize,
    /// Output width.
    pub d_out: usize,
    /// W, [d_in, d_out] row-major.
    pub weight: Vec<f32>,
    /// b, [d_out].
    pub bias: Vec<f32>,
}

impl DenseLayer {
    /// Checks that the layer maps `d_in` to `d_out` values, holds that many weights and
    /// biases, and that all are finite; the message says what is wrong.
    pub fn check(&self, d_in: usize, d_out: usize) -> std::result::Result<(), String> {
        if self.d_in != d_in
            || self.d_out != d_out
            || self.weight.len() != d_in * d_out
            || self.bias.len() != d_out
        {
            return Err("has the wrong shape".to_string());
        }
        match self.weight.iter().chain(&self.bias).position(|v| !v.is_finite()) {
            Some(i) => Err(format!("non-finite weight (value {i})")),
            None => Ok(()),
        }
    }

    /// y = x · W + b, optionally followed by ReLU. `x.len()` = d_in, `y.len()` = d_out.
    pub fn forward(&self, x: &[f32], y: &mut [f32], relu: bool) {
        debug_assert!(x.len() == self.d_in && y.len() == self.d_out);
        y.copy_from_slice(&self.bias);
        // `max(1)`: a layer without outputs has no weights to walk (and `chunks_exact(0)`
        // panics).
        for (xi, row) in x.iter().zip(self.weight.chunks_exact(self.d_out.max(1))) {
            if *xi != 0.0 {
                for (yo, w) in y.iter_mut().zip(row) {
                    *yo += xi * w;
                }
            }
        }
        if relu {
            y.iter_mut().for_each(|v| *v = v.max(0.0));
        }
    }
}

/// A multilayer perceptron: ReLU after every layer but the last.
#[derive(Clone, Debug, PartialEq)]
pub struct Mlp {
    /// Layers, input first.
    pub layers: Vec<DenseLayer>,
}

impl Mlp {
    /// Bytes of its weights and biases.
    pub fn heap_bytes(&self) -> usize {
        self.layers.iter().map(|l| l.weight.len() + l.bias.len()).sum::<usize>() * std::mem::size_of::<f32>()
    }

    /// The output for one input (`x.len()` = first layer's d_in).
    pub fn forward(&self, x: &[f32]) -> Vec<f32> {
        let mut h = x.to_vec();
        for (i, layer) in self.layers.iter().enumerate() {
            let mut y = vec![0.0; layer.d_out];
            layer.forward(&h, &mut y, i + 1 < self.layers.len());
            h = y;
        }
        h
    }

    /// The same net without the hidden units that are zero after ReLU for every input in
    /// `boxes` (each box one interval per input, low ≤ high), and how many went. Proved by
    /// interval bounds, box by box in f64: a unit goes only if the upper bound of its
    /// pre-activation is negative in every box by more than the rounding any f32 evaluation
    /// of the chain could add (each layer's bounds widened by (d_in + 2) · 2⁻²³ times the sum
    /// of the magnitudes of its terms, which also covers the rounding of the inputs to the
    /// next layer). A removed unit contributes exact zeros to the next layer, which a sum
    /// over inputs in order skips without changing a bit (the vector kernels skip zero rows
    /// already), so inside the boxes the pruned net gives the same bits. The last hidden
    /// layer is kept whole: the output layer's sums run over its units in vector lanes, and
    /// moving a unit to another lane would change their rounding.
    pub fn without_never_active_units<B: AsRef<[(f64, f64)]>>(&self, boxes: &[B]) -> (Mlp, usize) {
        // The hidden layers that may lose units: all but the last hidden one, whose bounds
        // are therefore never needed.
        let prunable = self.layers.len().saturating_sub(2);
        if boxes.is_empty() || prunable == 0 {
            return (self.clone(), 0);
        }
        let mut active: Vec<Vec<bool>> = self.layers[..prunable].iter().map(|l| vec![false; l.d_out]).collect();
        for b in boxes {
            let mut bounds: Vec<(f64, f64)> = b.as_ref().to_vec();
            for (layer, active) in self.layers[..prunable].iter().zip(active.iter_mut()) {
                if bounds.len() != layer.d_in {
                    return (self.clone(), 0);
                }
                let gamma = (layer.d_in + 2) as f64 * f64::from(f32::EPSILON);
                bounds = (0..layer.d_out)
                    .map(|o| {
                        let bias = f64::from(layer.bias[o]);
                        let (mut lo, mut hi, mut magnitude) = (bias, bias, bias.abs());
                        for (i, &(a, b)) in bounds.iter().enumerate() {
                            let w = f64::from(layer.weight[i * layer.d_out + o]);
                            let (p, q) = (w * a, w * b);
                            lo += p.min(q);
                            hi += p.max(q);
                            magnitude += p.abs().max(q.abs());
                        }
                        let margin = gamma * magnitude;
                        if hi + margin >= 0.0 {
                            active[o] = true;
                        }
                        ((lo - margin).max(0.0), (hi + margin).max(0.0))
                    })
                    .collect();
            }
        }
        // A layer keeps at least one unit (a constant net is still a net).
        for keep in &mut active {
            if !keep.iter().any(|&k| k) {
                keep[0] = true;
            }
        }
        let removed = active.iter().flatten().filter(|&&k| !k).count();
        if removed == 0 {
            return (self.clone(), 0);
        }
        let mut layers = self.layers.clone();
        for (k, keep) in active.iter().enumerate() {
            // Layer k loses output columns, layer k + 1 the matching input rows.
            let (out, next) = (&self.layers[k], &self.layers[k + 1]);
            let kept: Vec<usize> = (0..out.d_out).filter(|&o| keep[o]).collect();
            let layer = &layers[k];
            let bias = kept.iter().map(|&o| layer.bias[o]).collect();
            let weight = (0..layer.d_in)
                .flat_map(|i| kept.iter().map(move |&o| layer.weight[i * out.d_out + o]))
                .collect();
            layers[k].bias = bias;
            layers[k].weight = weight;
            layers[k].d_out = kept.len();
            layers[k + 1].weight = kept
                .iter()
                .flat_map(|&i| next.weight[i * next.d_out..(i + 1) * next.d_out].iter().copied())
                .collect();
            layers[k + 1].d_in = kept.len();
        }
        (Mlp { layers }, removed)
    }
}

/// The set encoder of the trained model: per sample [6D network input ‖ 3 mapped values] →
/// layers → z, ReLU after every layer (its last included, so z ≥ 0), z = mean over the
/// samples.
///
/// A sample is the target net's input of [`crate::brdf_coords::network_input`] (6 values)
/// followed by the mapped value y = [`MappingForm::forward`] of the measured f_r (1/sr) per
/// RGB channel, with the file's mapping, ε and f_ref at the same coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct Encoder {
    /// Layers, input first: 9 → hidden... → latent_dim (9 128 128 128 latent_dim by default).
    pub layers: Vec<DenseLayer>,
    /// Share (in [0, 1]) of the points whose θh was drawn with MERL's spacing θh = u²·π/2
    /// (u uniform in [0, 1)) when the encoder was trained; the others have θh uniform in
    /// [0, π/2]. Encoding must draw its samples the same way.
    pub peak_share: f32,
}

impl Encoder {
    /// Width of one encoder sample: 6D network input ‖ 3 mapped values.
    pub const INPUT_WIDTH: usize = 9;

    /// Width of the encoder's output, z (latent_dim in a valid file).
    pub fn output_width(&self) -> usize {
        self.layers.last().map_or(Self::INPUT_WIDTH, |l| l.d_out)
    }

    /// The reference forward pass in f32: every layer with ReLU on each sample, then the mean
    /// over the samples (summed in f64). No samples give zeros of the output width.
    ///
    /// # Panics
    /// If the layers do not chain (those of a latent file that was read do).
    pub fn encode(&self, samples: &[[f32; 9]]) -> Vec<f32> {
        let width = self.output_width();
        let mut sum = vec![0.0f64; width];
        for sample in samples {
            let mut h = sample.to_vec();
            for layer in &self.layers {
                let mut y = vec![0.0; layer.d_out];
                layer.forward(&h, &mut y, true);
                h = y;
            }
            sum.iter_mut()
                .zip(&h)
                .for_each(|(s, v)| *s += f64::from(*v));
        }
        let n = samples.len().max(1) as f64;
        sum.into_iter().map(|s| (s / n) as f32).collect()
    }
}

/// Decodes latent code `z` into the target net (the hypernetwork forward pass in f32): head
/// `2k` of `heads` gives the weights and head `2k + 1` the biases of target layer `k`, whose
/// shape is `target_layers[k]` (d_in, d_out); one MLP with ReLU after every hidden layer and
/// a linear output y. The code's output `offset` (per channel of the last layer) is added to
/// the output bias and its `residual` (empty: none; one slice per head in order, the output
/// bias's head excepted) to the other parameters.
///
/// # Panics
/// If the heads do not make the layers' parameters, the target net does not end in
/// `offset.len()` outputs, or a non-empty residual is shorter than the heads' outputs less
/// the output bias.
pub fn decode_target_net(
    heads: &[Mlp],
    target_layers: &[(usize, usize)],
    z: &[f32],
    offset: [f32; 3],
    residual: &[f32],
) -> Mlp {
    let mut outputs: Vec<Vec<f32>> = heads.iter().map(|head| head.forward(z)).collect();
    if !residual.is_empty() {
        // One slice per head in order, the output bias's head excepted (the offset's).
        let mut rest = residual;
        let last = outputs.len() - 1;
        for out in &mut outputs[..last] {
            let (head, tail) = rest.split_at(out.len());
            out.iter_mut().zip(head).for_each(|(v, d)| *v += d);
            rest = tail;
        }
    }
    let mut layers: Vec<DenseLayer> = target_layers
        .iter()
        .enumerate()
        .map(|(k, &(d_in, d_out))| DenseLayer {
            d_in,
            d_out,
            weight: outputs[2 * k].clone(),
            bias: outputs[2 * k + 1].clone(),
        })
        .collect();
    let last = layers.last_mut().expect("a target net has a layer");
    assert_eq!(last.bias.len(), offset.len(), "one offset per output");
    last.bias.iter_mut().zip(offset).for_each(|(b, d)| *b += d);
    Mlp { layers }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(d_in: usize, d_out: usize, weight: Vec<f32>, bias: Vec<f32>) -> DenseLayer {
        DenseLayer { d_in, d_out, weight, bias }
    }

    /// A unit that no input of the boxes switches on goes; one that only a corner of the
    /// domain switches on stays, as does every unit of the last hidden layer; the pruned net
    /// gives the same bits inside the boxes, the corner included.
    #[test]
    fn never_active_units_go_and_the_rest_give_the_same_bits() {
        // Inputs (x0, x1), x0 ∈ [0, 1], x1 ∈ [−1, 1]. Hidden 1: u0 = relu(0.1 x0 + 0.1 x1 − 5)
        // is never on; u1 = relu(x0 − 0.99) only for x0 > 0.99; u2 = relu(x1). Hidden 2 (the
        // last): v0 = relu(u0 − 1) is never on but stays; v1 = relu(u0 + u1 + u2).
        let mlp = Mlp {
            layers: vec![
                layer(2, 3, vec![0.1, 1.0, 0.0, 0.1, 0.0, 1.0], vec![-5.0, -0.99, 0.0]),
                layer(3, 2, vec![1.0, 1.0, 0.0, 1.0, 0.0, 1.0], vec![-1.0, 0.0]),
                layer(2, 1, vec![2.0, 3.0], vec![0.5]),
            ],
        };
        let boxes: Vec<[(f64, f64); 2]> = (0..4).map(|k| [(k as f64 / 4.0, (k + 1) as f64 / 4.0), (-1.0, 1.0)]).collect();
        let (pruned, removed) = mlp.without_never_active_units(&boxes);
        assert_eq!(removed, 1);
        assert_eq!((pruned.layers[0].d_out, pruned.layers[1].d_in, pruned.layers[1].d_out), (2, 2, 2));
        assert_eq!(pruned.layers[0].bias, vec![-0.99, 0.0]);
        assert_eq!(pruned.layers[1].weight, vec![0.0, 1.0, 0.0, 1.0]);
        for i in 0..=200 {
            for x1 in [-1.0, -0.3, 0.0, 0.7, 1.0] {
                let x = [i as f32 / 200.0, x1];
                assert_eq!(pruned.forward(&x)[0].to_bits(), mlp.forward(&x)[0].to_bits(), "{x:?}");
            }
        }
        // The corner is why u1 stays: without it, x0 = 1 would lose u1's 0.01.
        assert!(mlp.forward(&[1.0, 0.0])[0] > mlp.forward(&[0.5, 0.0])[0]);
        // Nothing is proved over no boxes, nor over boxes of the wrong width.
        assert_eq!(mlp.without_never_active_units::<[(f64, f64); 2]>(&[]).1, 0);
        assert_eq!(mlp.without_never_active_units(&[[(0.0, 1.0); 3]]).1, 0);
    }
}

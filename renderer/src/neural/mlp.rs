//! The reference f32 forward passes of the trained model stored in a latent file: dense
//! layers, the hypernetwork heads that decode a latent code into a target net, and the set
//! encoder. (The target net is evaluated fast by [`super::target_net::TargetNet`].)
//!
//! Dense layers compute y = x · W + b with W stored [d_in, d_out] row-major (as NBRDF's `.npy`
//! tensors and burn's `Linear`).

use crate::formats::latent_file::LatentFile;

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
    /// If the layers do not chain (a file read by [`LatentFile::read`] is consistent).
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

impl LatentFile {
    /// Decodes a latent code into the target net (hypernetwork forward pass in f32): one MLP
    /// with ReLU after every hidden layer and a linear output y, the code's output offset
    /// (per channel of the last layer) added to its output bias and its residual (empty:
    /// none; see [`crate::formats::latent_file::NamedLatent::residual`]) to the other
    /// parameters.
    ///
    /// # Panics
    /// If `z.len()` differs from `latent_dim`, the target net does not end in
    /// `offset.len()` outputs, or the residual is neither empty nor
    /// [`LatentFile::residual_len`] long (a file read by [`LatentFile::read`] is
    /// consistent; check user-made codes first).
    pub fn decode(&self, z: &[f32], offset: [f32; 3], residual: &[f32]) -> Mlp {
        assert_eq!(z.len(), self.latent_dim, "latent code size");
        assert!(
            residual.is_empty() || residual.len() == self.residual_len(),
            "residual size"
        );
        let mut outputs: Vec<Vec<f32>> = self
            .hypernetwork
            .iter()
            .map(|head| head.forward(z))
            .collect();
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
        let mut layers: Vec<DenseLayer> = self
            .target_layers()
            .into_iter()
            .enumerate()
            .map(|(k, (d_in, d_out))| DenseLayer {
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

}

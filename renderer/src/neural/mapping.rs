//! The log-relative mapping between BRDF values and what the neural networks output, and its
//! bounds.

/// Largest mapped value y the renderer uses: e^80 ≈ 5.5e34 times a reference below ~1e3 keeps
/// f_r finite whatever the weights.
pub const MAX_LOG_VALUE: f32 = 80.0;

/// The log-relative mapping between f_r and the network's output y (per channel, ε > 0,
/// f_ref the reference BRDF at the same coordinates).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MappingForm {
    /// The talk's form: y = ln((f + ε) / (f_ref + ε)); f = e^y (f_ref + ε) − ε.
    Talk,
    /// The authors' code: y = ln(1 + (f + ε) / (f_ref + ε)); f = (e^y − 1)(f_ref + ε) − ε.
    Code,
}

impl MappingForm {
    /// y of a BRDF value `f` (1/sr, ≥ 0) given `f_ref` (1/sr, ≥ 0).
    #[inline]
    pub fn forward(self, f: f32, f_ref: f32, epsilon: f32) -> f32 {
        let r = (f + epsilon) / (f_ref + epsilon);
        match self {
            MappingForm::Talk => r.ln(),
            MappingForm::Code => r.ln_1p(),
        }
    }

    /// f_r (1/sr) of a mapped value `y`; not clamped (callers clamp to ≥ 0).
    #[inline]
    pub fn inverse(self, y: f32, f_ref: f32, epsilon: f32) -> f32 {
        let e = match self {
            MappingForm::Talk => y.exp(),
            MappingForm::Code => y.exp_m1(),
        };
        e * (f_ref + epsilon) - epsilon
    }

    /// The byte the latent file stores for the form.
    pub(crate) fn code(self) -> u8 {
        match self {
            MappingForm::Talk => 0,
            MappingForm::Code => 1,
        }
    }
}


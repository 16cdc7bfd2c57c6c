//! Measured BRDFs bound to materials (tabulated MERL, NBRDF networks); being written.
use crate::Rgb;
use glam::{Vec2, Vec3};

/// A measured BSDF shared by every shading point of the materials bound to it.
#[derive(Debug)]
pub enum MeasuredBsdf {}

impl MeasuredBsdf {
    /// Loads the BSDF named by a binding specification such as `merl:path.binary`.
    pub fn load(spec: &str) -> crate::Result<Self> {
        Err(crate::Error::UnknownName {
            what: "BRDF binding kind",
            name: spec.to_string(),
            available: Vec::new(),
        })
    }
}

impl super::Bxdf for MeasuredBsdf {
    fn eval(&self, _wo: Vec3, _wi: Vec3) -> Rgb {
        match *self {}
    }
    fn pdf(&self, _wo: Vec3, _wi: Vec3) -> f32 {
        match *self {}
    }
    fn sample(&self, _wo: Vec3, _u: Vec2, _uc: f32) -> Option<super::BsdfSample> {
        match *self {}
    }
}

//! Mesh primitives: accessors checked before they are read, triangle modes assembled into
//! triangle lists, positions and normals transformed to world space.

use super::*;

impl Loader<'_> {
    /// One primitive's triangles moved by `world` (its vertices read in the mesh's space,
    /// missing normals and tangents computed there, then [`Geometry::transform`]ed), with
    /// material ids set.
    pub(super) fn primitive(&mut self, mesh: &str, primitive: &Primitive, world: Mat4) -> Result<Geometry> {
        let index = primitive.index();
        let mode = primitive.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            return Err(self.invalid(format!(
                "unsupported primitive mode {} in mesh '{mesh}' (only triangles, strips and fans)",
                mode_name(mode)
            )));
        }
        let what = |attribute: &str| format!("{attribute} of primitive {index} in mesh '{mesh}'");
        let buffers = self.buffers;
        let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));

        let positions_accessor = primitive
            .get(&::gltf::Semantic::Positions)
            .ok_or_else(|| self.invalid(format!("{} is missing", what("POSITION"))))?;
        self.check_accessor(
            &positions_accessor,
            &what("POSITION"),
            &[DataType::F32],
            Dimensions::Vec3,
        )?;
        let local_positions: Vec<Vec3> = reader
            .read_positions()
            .ok_or_else(|| self.invalid(format!("cannot read {}", what("POSITION"))))?
            .map(Vec3::from_array)
            .collect();
        let vertex_count = local_positions.len();

        let local_normals: Option<Vec<Vec3>> = match primitive.get(&::gltf::Semantic::Normals) {
            Some(accessor) => {
                self.check_accessor(
                    &accessor,
                    &what("NORMAL"),
                    &[DataType::F32],
                    Dimensions::Vec3,
                )?;
                let normals: Vec<Vec3> = reader
                    .read_normals()
                    .ok_or_else(|| self.invalid(format!("cannot read {}", what("NORMAL"))))?
                    .map(Vec3::from_array)
                    .collect();
                self.check_count(normals.len(), vertex_count, &what("NORMAL"))?;
                Some(normals)
            }
            None => None,
        };

        let tex_coords = |set: u32| -> Result<Option<Vec<Vec2>>> {
            let Some(accessor) = primitive.get(&::gltf::Semantic::TexCoords(set)) else {
                return Ok(None);
            };
            let name = what(&format!("TEXCOORD_{set}"));
            self.check_accessor(&accessor, &name, &[DataType::F32, DataType::U8, DataType::U16], Dimensions::Vec2)?;
            let uvs: Vec<Vec2> = reader
                .read_tex_coords(set)
                .ok_or_else(|| self.invalid(format!("cannot read {name}")))?
                .into_f32()
                .map(Vec2::from_array)
                .collect();
            self.check_count(uvs.len(), vertex_count, &name)?;
            Ok(Some(uvs))
        };
        let uvs = tex_coords(0)?.unwrap_or_else(|| vec![Vec2::ZERO; vertex_count]);
        let uvs1 = tex_coords(1)?.unwrap_or_default();

        let indices: Vec<u32> = match primitive.indices() {
            Some(accessor) => {
                self.check_accessor(
                    &accessor,
                    &what("indices"),
                    &[DataType::U8, DataType::U16, DataType::U32],
                    Dimensions::Scalar,
                )?;
                reader
                    .read_indices()
                    .ok_or_else(|| self.invalid(format!("cannot read {}", what("indices"))))?
                    .into_u32()
                    .collect()
            }
            None => (0..u32::try_from(vertex_count)
                .map_err(|_| self.invalid(format!("too many vertices in {}", what("POSITION"))))?)
                .collect(),
        };
        if let Some(&bad) = indices.iter().find(|&&i| i as usize >= vertex_count) {
            return Err(self.invalid(format!(
                "index {bad} out of range ({vertex_count} vertices) in primitive {index} of mesh '{mesh}'"
            )));
        }
        let triangles = assemble_triangles(mode, &indices).ok_or_else(|| {
            self.invalid(format!(
                "{} index count {} is not a multiple of 3 in primitive {index} of mesh '{mesh}'",
                mode_name(mode),
                indices.len()
            ))
        })?;

        let positions = local_positions;
        let normals = match local_normals {
            Some(local) => {
                let unit: Vec<Option<Vec3>> = local.iter().map(|n| n.try_normalize()).collect();
                if unit.iter().all(Option::is_some) {
                    unit.into_iter().flatten().collect()
                } else {
                    let smooth = smooth_vertex_normals(&positions, &triangles);
                    unit.into_iter().zip(smooth).map(|(n, s)| n.unwrap_or(s)).collect()
                }
            }
            None => smooth_vertex_normals(&positions, &triangles),
        };

        let material_id = match primitive.material().index() {
            Some(i) => u32::try_from(i).map_err(|_| self.invalid("too many materials"))?,
            None => self.default_material_id()?,
        };
        let normal_map_set = self
            .scene
            .materials
            .get(material_id as usize)
            .and_then(|m| m.normal_texture)
            .map(|n| n.texture.tex_coord);
        let tangents = match normal_map_set {
            None => Vec::new(),
            Some(set) => match primitive.get(&::gltf::Semantic::Tangents) {
                Some(accessor) => {
                    let name = what("TANGENT");
                    self.check_accessor(&accessor, &name, &[DataType::F32], Dimensions::Vec4)?;
                    let local: Vec<Vec4> = reader
                        .read_tangents()
                        .ok_or_else(|| self.invalid(format!("cannot read {name}")))?
                        .map(Vec4::from_array)
                        .collect();
                    self.check_count(local.len(), vertex_count, &name)?;
                    local
                        .iter()
                        .map(|t| match t.truncate().try_normalize() {
                            Some(xyz) if t.w.is_finite() => xyz.extend(if t.w < 0.0 { -1.0 } else { 1.0 }),
                            _ => Vec4::ZERO,
                        })
                        .collect()
                }
                None => {
                    let uvs = if set == 1 && !uvs1.is_empty() { &uvs1 } else { &uvs };
                    mikktspace_tangents(&positions, &normals, uvs, &triangles)
                }
            },
        };
        let material_ids = vec![material_id; triangles.len()];
        let mut part = Geometry {
            positions,
            normals,
            uvs,
            uvs1,
            tangents,
            triangles,
            material_ids,
        };
        part.transform(world);
        if part.positions.iter().any(|p| !p.is_finite()) {
            return Err(self.invalid(format!("non-finite vertex position in mesh '{mesh}'")));
        }
        Ok(part)
    }

    /// Checks what the `gltf` crate's readers assume but do not check, so reading can
    /// neither panic nor silently truncate: component type and dimensions, a non-zero count,
    /// a buffer view (sparse accessors are not supported), a stride at least the element
    /// size, and the accessed range inside the view and the view inside its buffer.
    pub(super) fn check_accessor(
        &self,
        accessor: &Accessor,
        what: &str,
        types: &[DataType],
        dimensions: Dimensions,
    ) -> Result<()> {
        let i = accessor.index();
        if accessor.sparse().is_some() {
            return Err(self.invalid(format!("{what}: sparse accessor {i} is not supported")));
        }
        if !types.contains(&accessor.data_type()) || accessor.dimensions() != dimensions {
            return Err(self.invalid(format!(
                "{what}: accessor {i} has type {:?} {:?}, expected {dimensions:?} of {types:?}",
                accessor.dimensions(),
                accessor.data_type()
            )));
        }
        if accessor.count() == 0 {
            return Err(self.invalid(format!("{what}: accessor {i} has count 0")));
        }
        let view = accessor
            .view()
            .ok_or_else(|| self.invalid(format!("{what}: accessor {i} has no bufferView")))?;
        let element = accessor.size();
        let stride = view.stride().unwrap_or(element);
        if stride < element {
            return Err(self.invalid(format!(
                "{what}: bufferView {} has byteStride {stride}, smaller than accessor {i}'s {element}-byte elements",
                view.index()
            )));
        }
        let end = stride
            .checked_mul(accessor.count() - 1)
            .and_then(|n| n.checked_add(element))
            .and_then(|n| n.checked_add(accessor.offset()));
        if end.is_none_or(|end| end > view.length()) {
            return Err(self.invalid(format!(
                "{what}: accessor {i} reads past the end of bufferView {}",
                view.index()
            )));
        }
        let buffer_len = self.buffers.get(view.buffer().index()).map_or(0, Vec::len);
        if view
            .offset()
            .checked_add(view.length())
            .is_none_or(|end| end > buffer_len)
        {
            return Err(self.invalid(format!(
                "{what}: bufferView {} reads past the end of buffer {} ({buffer_len} bytes)",
                view.index(),
                view.buffer().index()
            )));
        }
        Ok(())
    }

    pub(super) fn check_count(&self, count: usize, vertex_count: usize, what: &str) -> Result<()> {
        if count == vertex_count {
            Ok(())
        } else {
            Err(self.invalid(format!(
                "{what} has {count} elements but POSITION has {vertex_count}"
            )))
        }
    }
}

/// Per-vertex tangents of an indexed triangle mesh by MikkTSpace (the algorithm glTF names
/// for meshes without TANGENT, run in the mesh's space), with the normal map's image up as the bitangent: texture
/// coordinates are given to it with v flipped (glTF's v points down the image). Each vertex
/// takes the tangent of its last corner; a vertex MikkTSpace gives none (degenerate texture
/// coordinates, no triangle) gets zero, which shading reads as "no normal map here".
pub(super) fn mikktspace_tangents(positions: &[Vec3], normals: &[Vec3], uvs: &[Vec2], triangles: &[[u32; 3]]) -> Vec<Vec4> {
    struct Mesh<'a> {
        positions: &'a [Vec3],
        normals: &'a [Vec3],
        uvs: &'a [Vec2],
        triangles: &'a [[u32; 3]],
        tangents: Vec<Vec4>,
    }
    impl bevy_mikktspace::Geometry for Mesh<'_> {
        fn num_faces(&self) -> usize {
            self.triangles.len()
        }
        fn num_vertices_of_face(&self, _face: usize) -> usize {
            3
        }
        fn position(&self, face: usize, vert: usize) -> [f32; 3] {
            self.positions[self.triangles[face][vert] as usize].to_array()
        }
        fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
            self.normals[self.triangles[face][vert] as usize].to_array()
        }
        fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
            let uv = self.uvs[self.triangles[face][vert] as usize];
            [uv.x, 1.0 - uv.y]
        }
        fn set_tangent(&mut self, tangent_space: Option<bevy_mikktspace::TangentSpace>, face: usize, vert: usize) {
            let tangent = tangent_space.map_or(Vec4::ZERO, |t| Vec4::from_array(t.tangent_encoded()));
            self.tangents[self.triangles[face][vert] as usize] = if tangent.is_finite() { tangent } else { Vec4::ZERO };
        }
    }
    let mut mesh = Mesh { positions, normals, uvs, triangles, tangents: vec![Vec4::ZERO; positions.len()] };
    // The error type has no variants: generation cannot fail.
    let _ = bevy_mikktspace::generate_tangents(&mut mesh);
    mesh.tangents
}

/// The glTF spelling of a primitive mode.
pub(super) fn mode_name(mode: Mode) -> &'static str {
    match mode {
        Mode::Points => "POINTS",
        Mode::Lines => "LINES",
        Mode::LineLoop => "LINE_LOOP",
        Mode::LineStrip => "LINE_STRIP",
        Mode::Triangles => "TRIANGLES",
        Mode::TriangleStrip => "TRIANGLE_STRIP",
        Mode::TriangleFan => "TRIANGLE_FAN",
    }
}

/// Triangle list from a triangle mode's index sequence (glTF 2.0 § 3.7.2.1 orders strips as
/// (i, i + 1 + i % 2, i + 2 - i % 2) and fans as (i + 1, i + 2, 0)); `None` when a
/// TRIANGLES list's length is not a multiple of 3.
pub(super) fn assemble_triangles(mode: Mode, indices: &[u32]) -> Option<Vec<[u32; 3]>> {
    let n = indices.len();
    match mode {
        Mode::TriangleStrip => Some(
            (0..n.saturating_sub(2))
                .map(|i| [indices[i], indices[i + 1 + i % 2], indices[i + 2 - i % 2]])
                .collect(),
        ),
        Mode::TriangleFan => Some(
            (1..n.saturating_sub(1))
                .map(|i| [indices[i], indices[i + 1], indices[0]])
                .collect(),
        ),
        _ => n.is_multiple_of(3).then(|| {
            indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect()
        }),
    }
}

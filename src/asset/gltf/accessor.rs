//! Accessors: typed, bounds-checked reads of buffer views.

use super::*;

/// Strided elements inside a buffer view, bounds already checked.
pub(super) struct Elements<'b> {
    pub(super) bytes: &'b [u8],
    pub(super) stride: usize,
    pub(super) size: usize,
}

impl<'b> Elements<'b> {
    pub(super) fn get(&self, i: usize) -> Option<&'b [u8]> {
        let start = i.checked_mul(self.stride)?;
        self.bytes.get(start..start.checked_add(self.size)?)
    }
}

/// Where an accessor's values are, checked against its view and buffer.
pub(super) struct AccessorData<'b> {
    pub(super) count: usize,
    pub(super) component: ComponentType,
    pub(super) normalized: bool,
    pub(super) base: Option<Elements<'b>>,
    /// Sparse substitutions: element indices and their values.
    pub(super) sparse: Option<(Vec<usize>, Elements<'b>)>,
}

impl<'a> Doc<'a> {
    pub(super) fn invalid(&self, at: impl Into<String>, reason: impl Into<String>) -> GltfError {
        invalid(self.file, at, reason)
    }

    /// The bytes of buffer view `view`, and its stride.
    pub(super) fn view_bytes(
        &self,
        view: usize,
        at: &str,
    ) -> Result<(&'a [u8], Option<usize>), GltfError> {
        let Some(v) = self.root.buffer_views.get(view) else {
            return Err(self.invalid(at, format!("bufferView {view} does not exist")));
        };
        let b = v.buffer.value();
        let (Some(data), Some(buffer)) = (self.buffers.get(b), self.root.buffers.get(b)) else {
            return Err(self.invalid(at, format!("bufferView {view}: buffer {b} does not exist")));
        };
        let start = v.byte_offset.map_or(0, |o| o.0);
        let length = v.byte_length.0;
        let limit = buffer.byte_length.0.min(data.len() as u64);
        let bytes = start
            .checked_add(length)
            .filter(|&end| end <= limit)
            .and_then(|end| data.get(usize::try_from(start).ok()?..usize::try_from(end).ok()?));
        let Some(bytes) = bytes else {
            return Err(self.invalid(
                at,
                format!(
                    "bufferView {view} spans bytes {start}..{} but buffer {b} has {limit}",
                    start.saturating_add(length)
                ),
            ));
        };
        Ok((bytes, v.byte_stride.map(|s| s.0).filter(|&s| s > 0)))
    }

    /// `count` elements of `size` bytes from `offset` in view `view`, every one in bounds.
    /// `packed` ignores the view's byteStride (sparse data is always tightly packed).
    pub(super) fn elements(
        &self,
        view: usize,
        offset: u64,
        count: usize,
        size: usize,
        packed: bool,
        at: &str,
    ) -> Result<Elements<'a>, GltfError> {
        let (view_data, view_stride) = self.view_bytes(view, at)?;
        let stride = if packed {
            size
        } else {
            view_stride.unwrap_or(size)
        };
        if stride < size {
            return Err(self.invalid(
                at,
                format!(
                    "bufferView {view}'s byteStride {stride} is less than the element size {size}"
                ),
            ));
        }
        let offset_usize = usize::try_from(offset).ok();
        let end = match count.checked_sub(1) {
            None => offset_usize,
            Some(last) => last
                .checked_mul(stride)
                .and_then(|x| x.checked_add(size))
                .and_then(|x| x.checked_add(offset_usize?)),
        };
        let bytes = end
            .filter(|&end| end <= view_data.len())
            .and_then(|_| view_data.get(offset_usize?..));
        let Some(bytes) = bytes else {
            return Err(self.invalid(
                at,
                format!(
                    "{count} elements of {size} bytes (stride {stride}) from byte {offset} do not \
                     fit in bufferView {view} ({} bytes)",
                    view_data.len()
                ),
            ));
        };
        Ok(Elements {
            bytes,
            stride,
            size,
        })
    }

    /// Locates accessor `index`, which must be of type `expected` with at most `max_count`
    /// elements; nothing is read yet, but every element is known to be in bounds.
    pub(super) fn accessor(
        &self,
        index: usize,
        at: &str,
        expected: Type,
        max_count: usize,
    ) -> Result<AccessorData<'a>, GltfError> {
        let at = format!("{at}, accessor {index}");
        let Some(accessor) = self.root.accessors.get(index) else {
            return Err(self.invalid(at, "does not exist"));
        };
        let Some(count) = usize::try_from(accessor.count.0)
            .ok()
            .filter(|&c| c <= max_count)
        else {
            return Err(self.invalid(
                at,
                format!(
                    "count {} exceeds the limit of {max_count}",
                    accessor.count.0
                ),
            ));
        };
        let Checked::Valid(GenericComponentType(component)) = accessor.component_type else {
            return Err(self.invalid(at, "componentType is invalid"));
        };
        let Checked::Valid(ty) = accessor.type_ else {
            return Err(self.invalid(at, "type is invalid"));
        };
        if ty != expected {
            return Err(self.invalid(
                at,
                format!(
                    "type is {}, expected {}",
                    type_name(ty),
                    type_name(expected)
                ),
            ));
        }
        let size = component.size() * ty.multiplicity();
        let base = match accessor.buffer_view {
            Some(view) => Some(self.elements(
                view.value(),
                accessor.byte_offset.map_or(0, |o| o.0),
                count,
                size,
                false,
                &at,
            )?),
            None => {
                // Its elements are zeros (but for sparse substitutions): no more of them than
                // the file's buffers hold bytes, so that a small file cannot ask for gigabytes.
                let available: u64 = self.buffers.iter().map(|b| b.len() as u64).sum();
                if (count as u64).saturating_mul(size as u64) > available {
                    return Err(self.invalid(
                        at,
                        format!(
                            "has no bufferView, and its {count} elements of {size} bytes exceed \
                             the {available} bytes of the file's buffers"
                        ),
                    ));
                }
                None
            }
        };
        let sparse = match &accessor.sparse {
            None => None,
            Some(sparse) => {
                let at = format!("{at}, sparse");
                let Some(n) = usize::try_from(sparse.count.0).ok().filter(|&n| n <= count) else {
                    return Err(self.invalid(
                        at,
                        format!("count {} exceeds the accessor's {count}", sparse.count.0),
                    ));
                };
                let Checked::Valid(IndexComponentType(index_type)) = sparse.indices.component_type
                else {
                    return Err(self.invalid(at, "indices.componentType is invalid"));
                };
                if !is_unsigned(index_type) {
                    return Err(self.invalid(at, "indices.componentType is not unsigned"));
                }
                let index_elements = self.elements(
                    sparse.indices.buffer_view.value(),
                    sparse.indices.byte_offset.0,
                    n,
                    index_type.size(),
                    true,
                    &format!("{at}.indices"),
                )?;
                let mut indices = Vec::with_capacity(n);
                for k in 0..n {
                    let i = index_elements
                        .get(k)
                        .map_or(u32::MAX, |b| read_uint(b, index_type))
                        as usize;
                    if i >= count {
                        return Err(self.invalid(
                            at,
                            format!("index {i} (entry {k}) is out of range for count {count}"),
                        ));
                    }
                    indices.push(i);
                }
                let values = self.elements(
                    sparse.values.buffer_view.value(),
                    sparse.values.byte_offset.0,
                    n,
                    size,
                    true,
                    &format!("{at}.values"),
                )?;
                Some((indices, values))
            }
        };
        Ok(AccessorData {
            count,
            component,
            normalized: accessor.normalized,
            base,
            sparse,
        })
    }

    /// Decodes every element of `data` (bounds were checked by `accessor`).
    pub(super) fn read<T: Copy>(
        &self,
        data: &AccessorData<'a>,
        at: &str,
        zero: T,
        decode: impl Fn(&[u8]) -> T,
    ) -> Result<Vec<T>, GltfError> {
        let mut out = Vec::with_capacity(data.count);
        match &data.base {
            Some(elements) => {
                for i in 0..data.count {
                    let Some(bytes) = elements.get(i) else {
                        return Err(self.invalid(at, format!("element {i} is out of bounds")));
                    };
                    out.push(decode(bytes));
                }
            }
            None => out.resize(data.count, zero),
        }
        if let Some((indices, values)) = &data.sparse {
            for (k, &i) in indices.iter().enumerate() {
                let (Some(slot), Some(bytes)) = (out.get_mut(i), values.get(k)) else {
                    return Err(self.invalid(at, format!("sparse entry {k} is out of bounds")));
                };
                *slot = decode(bytes);
            }
        }
        Ok(out)
    }

    pub(super) fn read_vec3s(&self, accessor: usize, at: &str) -> Result<Vec<Vec3>, GltfError> {
        let data = self.accessor(accessor, at, Type::Vec3, MAX_ELEMENTS)?;
        let (component, normalized) = (data.component, data.normalized);
        let size = component.size();
        let values = self.read(&data, at, Vec3::ZERO, |b| {
            Vec3::new(
                read_float(b, 0, component, normalized),
                read_float(b, size, component, normalized),
                read_float(b, 2 * size, component, normalized),
            )
        })?;
        if let Some((k, v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(self.invalid(
                format!("{at}, accessor {accessor}"),
                format!("element {k} is not finite ({v})"),
            ));
        }
        Ok(values)
    }

    /// A VEC2 or VEC4 attribute (`N` components) as floats, every element finite.
    pub(super) fn read_floats<const N: usize>(
        &self,
        accessor: usize,
        at: &str,
    ) -> Result<Vec<[f32; N]>, GltfError> {
        let ty = if N == 2 { Type::Vec2 } else { Type::Vec4 };
        let data = self.accessor(accessor, at, ty, MAX_ELEMENTS)?;
        let (component, normalized) = (data.component, data.normalized);
        let size = component.size();
        let values = self.read(&data, at, [0.0; N], |b| {
            std::array::from_fn(|k| read_float(b, k * size, component, normalized))
        })?;
        if let Some(k) = values.iter().position(|v| v.iter().any(|x| !x.is_finite())) {
            return Err(self.invalid(
                format!("{at}, accessor {accessor}"),
                format!("element {k} is not finite"),
            ));
        }
        Ok(values)
    }

    pub(super) fn read_indices(&self, accessor: usize, at: &str) -> Result<Vec<u32>, GltfError> {
        let data = self.accessor(accessor, at, Type::Scalar, 3 * MAX_ELEMENTS)?;
        if !is_unsigned(data.component) || data.normalized {
            return Err(self.invalid(
                format!("{at}, accessor {accessor}"),
                "indices must be unsigned integers (UNSIGNED_BYTE, _SHORT or _INT)",
            ));
        }
        let component = data.component;
        self.read(&data, at, 0, |b| read_uint(b, component))
    }
}

pub(super) fn is_unsigned(component: ComponentType) -> bool {
    matches!(
        component,
        ComponentType::U8 | ComponentType::U16 | ComponentType::U32
    )
}

/// Component `offset` bytes into `b` as a float, normalised integers mapped to [-1, 1].
pub(super) fn read_float(
    b: &[u8],
    offset: usize,
    component: ComponentType,
    normalized: bool,
) -> f32 {
    let byte = |k: usize| b.get(offset + k).copied().unwrap_or(0);
    let (value, scale) = match component {
        ComponentType::F32 => return f32::from_le_bytes([byte(0), byte(1), byte(2), byte(3)]),
        ComponentType::I8 => (f32::from(byte(0) as i8), 127.0),
        ComponentType::U8 => (f32::from(byte(0)), 255.0),
        ComponentType::I16 => (f32::from(i16::from_le_bytes([byte(0), byte(1)])), 32767.0),
        ComponentType::U16 => (f32::from(u16::from_le_bytes([byte(0), byte(1)])), 65535.0),
        ComponentType::U32 => (
            u32::from_le_bytes([byte(0), byte(1), byte(2), byte(3)]) as f32,
            u32::MAX as f32,
        ),
    };
    if normalized {
        (value / scale).max(-1.0)
    } else {
        value
    }
}

/// An unsigned integer component (`u32::MAX` for other types, which callers reject first).
pub(super) fn read_uint(b: &[u8], component: ComponentType) -> u32 {
    let byte = |k: usize| b.get(k).copied().unwrap_or(0);
    match component {
        ComponentType::U8 => u32::from(byte(0)),
        ComponentType::U16 => u32::from(u16::from_le_bytes([byte(0), byte(1)])),
        ComponentType::U32 => u32::from_le_bytes([byte(0), byte(1), byte(2), byte(3)]),
        _ => u32::MAX,
    }
}

pub(super) fn type_name(ty: Type) -> &'static str {
    match ty {
        Type::Scalar => "SCALAR",
        Type::Vec2 => "VEC2",
        Type::Vec3 => "VEC3",
        Type::Vec4 => "VEC4",
        Type::Mat2 => "MAT2",
        Type::Mat3 => "MAT3",
        Type::Mat4 => "MAT4",
    }
}

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

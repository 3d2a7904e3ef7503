//! Reading a glTF accessor's elements after checking that every one lies inside its buffer
//! view, and its component type and count are what the attribute needs.

use gltf::accessor::{DataType, Dimensions};

use super::Reader;
use crate::error::{PrtError, Result};

impl Reader<'_> {
    /// The bytes of a buffer view (checked in [`Reader::load_buffers`]).
    pub(super) fn view_bytes(&self, view: &gltf::buffer::View) -> &[u8] {
        &self.st.buffers[view.buffer().index()][view.offset()..view.offset() + view.length()]
    }

    /// An accessor's elements as floats, `N` components each, converting normalised integers.
    /// `types` lists the component types accepted.
    pub(super) fn read_floats<const N: usize>(
        &self,
        accessor: &gltf::Accessor,
        field: &str,
        types: &[DataType],
    ) -> Result<Vec<[f32; N]>> {
        let dims = match accessor.dimensions() {
            Dimensions::Scalar => 1,
            Dimensions::Vec2 => 2,
            Dimensions::Vec3 => 3,
            Dimensions::Vec4 => 4,
            _ => 0,
        };
        let ty = accessor.data_type();
        if dims != N || !types.contains(&ty) || (ty != DataType::F32 && !accessor.normalized()) {
            return Err(self.accessor_error(
                accessor,
                field,
                format!(
                    "holds {:?} of {ty:?}{}; expected {N} components of {}",
                    accessor.dimensions(),
                    if accessor.normalized() {
                        " (normalised)"
                    } else {
                        ""
                    },
                    types
                        .iter()
                        .map(|t| format!("{t:?}"))
                        .collect::<Vec<_>>()
                        .join(" or ")
                ),
            ));
        }
        let raw = self.element_bytes(accessor, field, N * ty.size())?;
        Ok(raw
            .map(|e| {
                std::array::from_fn(|k| {
                    let c = &e[k * ty.size()..(k + 1) * ty.size()];
                    match ty {
                        DataType::F32 => f32::from_le_bytes([c[0], c[1], c[2], c[3]]),
                        DataType::U8 => c[0] as f32 / 255.0,
                        DataType::U16 => u16::from_le_bytes([c[0], c[1]]) as f32 / 65535.0,
                        DataType::I8 => (c[0] as i8 as f32 / 127.0).max(-1.0),
                        DataType::I16 => {
                            (i16::from_le_bytes([c[0], c[1]]) as f32 / 32767.0).max(-1.0)
                        }
                        DataType::U32 => u32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f32,
                    }
                })
            })
            .collect())
    }

    /// An index accessor's values.
    pub(super) fn read_indices(&self, accessor: &gltf::Accessor, field: &str) -> Result<Vec<u32>> {
        let ty = accessor.data_type();
        let ok = accessor.dimensions() == Dimensions::Scalar
            && matches!(ty, DataType::U8 | DataType::U16 | DataType::U32);
        if !ok {
            return Err(self.accessor_error(
                accessor,
                field,
                format!(
                    "holds {:?} of {ty:?}; indices are scalars of U8, U16 or U32",
                    accessor.dimensions()
                ),
            ));
        }
        let raw = self.element_bytes(accessor, field, ty.size())?;
        Ok(raw
            .map(|c| match ty {
                DataType::U8 => c[0] as u32,
                DataType::U16 => u16::from_le_bytes([c[0], c[1]]) as u32,
                _ => u32::from_le_bytes([c[0], c[1], c[2], c[3]]),
            })
            .collect())
    }

    pub(super) fn accessor_error(
        &self,
        accessor: &gltf::Accessor,
        field: &str,
        message: String,
    ) -> PrtError {
        self.error(format!("{field} (accessor {})", accessor.index()), message)
    }

    /// The bytes of each of an accessor's elements, `size` bytes each, after checking that
    /// they all lie inside its buffer view.
    pub(super) fn element_bytes<'s>(
        &'s self,
        accessor: &gltf::Accessor,
        field: &str,
        size: usize,
    ) -> Result<impl Iterator<Item = &'s [u8]> + 's> {
        if accessor.sparse().is_some() {
            return Err(self.accessor_error(
                accessor,
                field,
                "sparse accessors are not supported".into(),
            ));
        }
        let Some(view) = accessor.view() else {
            return Err(self.accessor_error(
                accessor,
                field,
                "has no bufferView (an all-zero attribute)".into(),
            ));
        };
        let count = accessor.count();
        let stride = view.stride().unwrap_or(size);
        if count == 0 {
            return Err(self.accessor_error(accessor, field, "has no elements".into()));
        }
        if stride < size {
            return Err(self.accessor_error(
                accessor,
                field,
                format!(
                    "byteStride {stride} of bufferView {} is less than its {size}-byte elements",
                    view.index()
                ),
            ));
        }
        let bytes = self.view_bytes(&view);
        let end = (count - 1)
            .checked_mul(stride)
            .and_then(|v| v.checked_add(size))
            .and_then(|v| v.checked_add(accessor.offset()));
        if end.is_none_or(|e| e > bytes.len()) {
            return Err(self.accessor_error(
                accessor,
                field,
                format!(
                    "{count} elements of {size} bytes every {stride} from byte {} run past the \
                     end of bufferView {} ({} bytes)",
                    accessor.offset(),
                    view.index(),
                    bytes.len()
                ),
            ));
        }
        let start = accessor.offset();
        Ok((0..count).map(move |i| &bytes[start + i * stride..start + i * stride + size]))
    }
}

//! The Haar matrix's group: each slot's scale code with, from version 7, its strips' counts,
//! places and values, or before it each column's entry count, entries' rows and values (made into
//! strips as they load).

use safetensors::tensor::Dtype;

use super::{ReadGroup, ShapeCheck, Tensor, ValueTensor, not_mine, taken};
use crate::error::{PrtError, Result};
use crate::store::container::Tensor as Out;
use crate::store::transport::legacy::{Columns, strips_of_columns};
use crate::store::transport::reader::TensorReader;
use crate::store::transport::strips::{Layout, STRIP_ROWS};
use crate::store::transport::{Quantization, Strips, TransportMeta, Values};

/// The Haar matrix: each slot's scale code with, from version 7, its strips' counts, places and
/// values, or before it each column's entry count, entries' rows and values.
#[derive(Default)]
pub(in crate::store::transport) struct MatrixTensors {
    pub(in crate::store::transport) col_scale: Option<Tensor<u8>>,
    pub(in crate::store::transport) strip_count: Option<Tensor<u8>>,
    pub(in crate::store::transport) strip_place: Option<Tensor<u8>>,
    pub(in crate::store::transport) strip_value: Option<ValueTensor>,
    pub(in crate::store::transport) col_count: Option<Tensor<u16>>,
    pub(in crate::store::transport) entry_row: Option<Tensor<u8>>,
    pub(in crate::store::transport) entry_value: Option<ValueTensor>,
}

impl MatrixTensors {
    pub(in crate::store::transport) const COL_SCALE: &str = "col_scale";
    pub(in crate::store::transport) const STRIP_COUNT: &str = "strip_count";
    pub(in crate::store::transport) const STRIP_PLACE: &str = "strip_place";
    pub(in crate::store::transport) const STRIP_VALUE: &str = "strip_value";
    pub(in crate::store::transport) const COL_COUNT: &str = "col_count";
    pub(in crate::store::transport) const ENTRY_ROW: &str = "entry_row";
    pub(in crate::store::transport) const ENTRY_VALUE: &str = "entry_value";
    pub(super) const STRIP_NAMES: [&str; 4] = [
        Self::COL_SCALE,
        Self::STRIP_COUNT,
        Self::STRIP_PLACE,
        Self::STRIP_VALUE,
    ];
    pub(super) const COLUMN_NAMES: [&str; 4] = [
        Self::COL_COUNT,
        Self::COL_SCALE,
        Self::ENTRY_ROW,
        Self::ENTRY_VALUE,
    ];

    /// The tensors of a matrix in strips, to write: `strip_count` and `col_scale` of shape
    /// `slots` ([B, C]), the strips' places and their values.
    pub(in crate::store::transport) fn write<'a>(
        slots: [usize; 2],
        counts: &'a [u8],
        codes: &'a [u8],
        index: &'a [u8],
        values: &'a Values,
    ) -> [(&'static str, Out<'a>); 4] {
        let s = index.len();
        let shape = vec![s, STRIP_ROWS];
        [
            (
                Self::STRIP_COUNT,
                Out::new(Dtype::U8, slots.to_vec(), counts),
            ),
            (Self::COL_SCALE, Out::new(Dtype::U8, slots.to_vec(), codes)),
            (Self::STRIP_PLACE, Out::new(Dtype::U8, vec![s], index)),
            (
                Self::STRIP_VALUE,
                match values {
                    Values::Q8(v) => Out::new(Dtype::I8, shape, v),
                    Values::Q16(v) => Out::new(Dtype::I16, shape, v),
                    Values::F32(v) => Out::new(Dtype::F32, shape, v),
                },
            ),
        ]
    }
}

impl MatrixTensors {
    /// The strips of the matrix laid out as `layout` with `block_row_start` and `c`
    /// coefficients, every tensor's shape checked by `expect` (errors by `bad`); columns of
    /// versions 3 to 6 made into strips.
    pub(in crate::store::transport) fn into_strips(
        self,
        layout: Layout,
        (block_row_start, c): (&[u32], usize),
        expect: ShapeCheck,
        bad: &dyn Fn(String) -> PrtError,
    ) -> Result<Strips> {
        let blocks = block_row_start.len() - 1;
        let (scale_shape, col_scale) = taken(self.col_scale, Self::COL_SCALE)?;
        expect(Self::COL_SCALE, &scale_shape, &[blocks, c])?;
        match self {
            MatrixTensors {
                col_count: Some((count_shape, counts)),
                entry_row: Some((entry_shape, entry_row)),
                entry_value: Some((value_shape, values)),
                ..
            } => {
                expect(Self::COL_COUNT, &count_shape, &[blocks, c])?;
                let nnz = entry_shape.first().copied().unwrap_or(0);
                expect(Self::ENTRY_ROW, &entry_shape, &[nnz])?;
                expect(Self::ENTRY_VALUE, &value_shape, &[nnz])?;
                let columns = Columns {
                    block_row_start,
                    c,
                    counts: &counts,
                    codes: &col_scale,
                    rows: &entry_row,
                };
                strips_of_columns(layout, columns, &values).map_err(bad)
            }
            MatrixTensors {
                strip_count: Some((count_shape, counts)),
                strip_place: Some((place_shape, place)),
                strip_value: Some((value_shape, values)),
                ..
            } => {
                expect(Self::STRIP_COUNT, &count_shape, &[blocks, c])?;
                let strips = place_shape.first().copied().unwrap_or(0);
                expect(Self::STRIP_PLACE, &place_shape, &[strips])?;
                expect(Self::STRIP_VALUE, &value_shape, &[strips, STRIP_ROWS])?;
                Strips::from_tables(layout, &counts, &col_scale, place, values).map_err(bad)
            }
            _ => Err(bad("neither columns nor strips were read".into())),
        }
    }
}

impl ReadGroup for MatrixTensors {
    fn read(&mut self, name: &str, reader: &mut TensorReader, meta: &TransportMeta) -> Result<()> {
        let q = meta.identity.quantization;
        match name {
            Self::COL_SCALE => self.col_scale = Some(reader.read(name, Dtype::U8)?),
            Self::STRIP_COUNT => self.strip_count = Some(reader.read(name, Dtype::U8)?),
            Self::STRIP_PLACE => self.strip_place = Some(reader.read(name, Dtype::U8)?),
            Self::STRIP_VALUE => self.strip_value = Some(read_values(reader, name, q)?),
            Self::COL_COUNT => self.col_count = Some(reader.read(name, Dtype::U16)?),
            Self::ENTRY_ROW => self.entry_row = Some(reader.read(name, Dtype::U8)?),
            Self::ENTRY_VALUE => self.entry_value = Some(read_values(reader, name, q)?),
            _ => return Err(not_mine(name)),
        }
        Ok(())
    }
}

/// Tensor `name` of stored values in quantisation `q`: its shape and values.
fn read_values(reader: &mut TensorReader, name: &str, q: Quantization) -> Result<ValueTensor> {
    Ok(match q {
        Quantization::Q8 => {
            let (s, v) = reader.read(name, Dtype::I8)?;
            (s, Values::Q8(v))
        }
        Quantization::Q16 => {
            let (s, v) = reader.read(name, Dtype::I16)?;
            (s, Values::Q16(v))
        }
        Quantization::F32 => {
            let (s, v) = reader.read(name, Dtype::F32)?;
            (s, Values::F32(v))
        }
    })
}

//! Reading a transport file's tensors by name, in the order its checksum covers them, each
//! straight into a typed table, with every offset and size checked first.

use std::io::{Read, Seek};
use std::path::Path;

use safetensors::tensor::Dtype;

use crate::error::{PrtError, Result};
use crate::store::container;

/// Reads the tensors of a file whose header `read_header` checked, by name, each straight into
/// a typed table. Offsets and sizes are checked against the header's dtype and shape and the file
/// before anything is allocated or read. The checksum of what was read, one part per tensor, is
/// kept as it goes (a load reads in the order the checksum covers); `progress(bytes, file size)`
/// follows the reads.
pub(super) struct TensorReader<'a> {
    path: &'a Path,
    tensors: &'a serde_json::Map<String, serde_json::Value>,
    data_start: u64,
    file: std::fs::File,
    file_len: u64,
    done: u64,
    sum: container::Checksum,
    progress: &'a dyn Fn(u64, u64),
}

impl<'a> TensorReader<'a> {
    pub(super) fn new(
        path: &'a Path,
        tensors: &'a serde_json::Map<String, serde_json::Value>,
        data_start: u64,
        file: std::fs::File,
        progress: &'a dyn Fn(u64, u64),
    ) -> Result<Self> {
        let file_len = file.metadata().map_err(|e| PrtError::io(path, e))?.len();
        Ok(TensorReader {
            path,
            tensors,
            data_start,
            file,
            file_len,
            done: 0,
            sum: container::Checksum::new(),
            progress,
        })
    }

    /// The checksum of the tensors read so far, in the order they were read.
    pub(super) fn checksum(&self) -> u64 {
        self.sum.value()
    }

    /// Tensor `name`'s dtype name, shape and byte range in the data; its size checked against
    /// the file.
    pub(super) fn locate(&self, name: &str) -> Result<(String, Vec<usize>, u64, u64)> {
        let bad = |why: &str| PrtError::file(self.path, format!("tensor `{name}` {why}"));
        let t = self.tensors.get(name).ok_or_else(|| bad("is missing"))?;
        let dtype = t
            .get("dtype")
            .and_then(|d| d.as_str())
            .ok_or_else(|| bad("has no dtype"))?;
        let shape = t
            .get("shape")
            .and_then(|s| s.as_array())
            .and_then(|a| {
                a.iter()
                    .map(|d| usize::try_from(d.as_u64()?).ok())
                    .collect::<Option<Vec<usize>>>()
            })
            .ok_or_else(|| bad("has a bad shape"))?;
        let offsets = t.get("data_offsets").and_then(|o| o.as_array());
        match offsets.and_then(|o| Some((o.first()?.as_u64()?, o.get(1)?.as_u64()?))) {
            Some((a, b)) if a <= b && self.data_start.checked_add(b) <= Some(self.file_len) => {
                Ok((dtype.to_string(), shape, a, b))
            }
            _ => Err(bad("has bad data_offsets")),
        }
    }

    /// Tensor `name`, which must be of `dtype`, as its shape and its values.
    pub(super) fn read<T: bytemuck::Pod>(
        &mut self,
        name: &str,
        dtype: Dtype,
    ) -> Result<(Vec<usize>, Vec<T>)> {
        let (found, shape, start, end) = self.locate(name)?;
        let bad = |why: String| PrtError::file(self.path, format!("tensor `{name}` {why}"));
        if found != format!("{dtype:?}") {
            return Err(bad(format!("has dtype {found}, expected {dtype:?}")));
        }
        let count = shape.iter().try_fold(1usize, |n, &d| n.checked_mul(d));
        let bytes = (end - start) as usize;
        let size = std::mem::size_of::<T>();
        if count.and_then(|n| n.checked_mul(dtype.bitsize() / 8)) != Some(bytes)
            || !bytes.is_multiple_of(size)
        {
            return Err(bad(format!(
                "of shape {shape:?} does not fill its {bytes} bytes"
            )));
        }
        let mut values: Vec<T> = Vec::new();
        values
            .try_reserve_exact(bytes / size)
            .map_err(|_| bad(format!("takes {bytes} bytes, which do not fit in memory")))?;
        values.resize(bytes / size, T::zeroed());
        self.seek(name, start)?;
        for piece in bytemuck::cast_slice_mut::<T, u8>(&mut values).chunks_mut(8 << 20) {
            self.read_into(name, piece)?;
            self.sum.update(piece);
        }
        self.sum.end_part();
        Ok((shape, values))
    }

    fn seek(&mut self, name: &str, start: u64) -> Result<()> {
        self.file
            .seek(std::io::SeekFrom::Start(self.data_start + start))
            .map(|_| ())
            .map_err(|e| PrtError::file(self.path, format!("tensor `{name}`: {e}")))
    }

    fn read_into(&mut self, name: &str, buf: &mut [u8]) -> Result<()> {
        self.file
            .read_exact(buf)
            .map_err(|e| PrtError::file(self.path, format!("tensor `{name}`: reading: {e}")))?;
        self.done += buf.len() as u64;
        (self.progress)(
            (self.data_start + self.done).min(self.file_len),
            self.file_len,
        );
        Ok(())
    }
}

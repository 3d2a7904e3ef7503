//! What a bake keeps and how it is stored: the thresholding budget, the quantised values, and the
//! transport file, in the container the volume file shares.

pub mod budget;
pub mod container;
pub mod quant;
pub mod transport;

//! The content hash that keys a scene's bakes: 64-bit FNV-1a over its files' bytes.

/// 64-bit FNV-1a, written out so the hash never changes with a dependency's version.
pub(super) struct Fnv1a(pub(super) u64);

impl Fnv1a {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;

    pub(super) fn new() -> Self {
        Fnv1a(Self::OFFSET)
    }

    pub(super) fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(Self::PRIME);
        }
    }

    /// Hashes a length-prefixed chunk, so that moving bytes from one input to the next changes
    /// the hash.
    pub(super) fn write_chunk(&mut self, bytes: &[u8]) {
        self.write(&(bytes.len() as u64).to_le_bytes());
        self.write(bytes);
    }
}

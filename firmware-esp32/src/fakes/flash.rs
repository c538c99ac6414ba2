//! A NOR flash in RAM with the ESP32's geometry (4 KiB erase sectors, 4-byte words), for the
//! twin's configuration store. NOR rules apply: erase sets bytes to 0xFF, writes can only clear
//! bits, misaligned or out-of-range access is an error.

use embedded_storage_async::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};

/// A flash error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RamFlashError(NorFlashErrorKind);

impl NorFlashError for RamFlashError {
    fn kind(&self) -> NorFlashErrorKind {
        self.0
    }
}

/// The RAM flash.
#[derive(Debug, Clone)]
pub struct RamFlash {
    bytes: Vec<u8>,
}

impl RamFlash {
    /// Erase sector size.
    pub const PAGE: u32 = 4096;

    /// An erased flash of `pages` sectors.
    pub fn new(pages: usize) -> Self {
        Self {
            bytes: vec![0xFF; pages * Self::PAGE as usize],
        }
    }

    /// Flip every byte of each occurrence of `pattern` (a test's way of corrupting a record);
    /// returns how many occurrences were found.
    pub fn corrupt_pattern(&mut self, pattern: &[u8]) -> usize {
        let mut found = 0;
        let mut i = 0;
        while i + pattern.len() <= self.bytes.len() {
            if &self.bytes[i..i + pattern.len()] == pattern {
                for b in &mut self.bytes[i..i + pattern.len()] {
                    *b ^= 0x5A;
                }
                found += 1;
                i += pattern.len();
            } else {
                i += 1;
            }
        }
        found
    }

    fn check(&self, offset: u32, len: usize, align: u32) -> Result<(), RamFlashError> {
        if !offset.is_multiple_of(align) || !(len as u32).is_multiple_of(align) {
            return Err(RamFlashError(NorFlashErrorKind::NotAligned));
        }
        if offset as usize + len > self.bytes.len() {
            return Err(RamFlashError(NorFlashErrorKind::OutOfBounds));
        }
        Ok(())
    }
}

impl ErrorType for RamFlash {
    type Error = RamFlashError;
}

impl ReadNorFlash for RamFlash {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), RamFlashError> {
        self.check(offset, bytes.len(), 1)?;
        let start = offset as usize;
        bytes.copy_from_slice(&self.bytes[start..start + bytes.len()]);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.bytes.len()
    }
}

impl NorFlash for RamFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = Self::PAGE as usize;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), RamFlashError> {
        if to < from {
            return Err(RamFlashError(NorFlashErrorKind::OutOfBounds));
        }
        self.check(from, (to - from) as usize, Self::PAGE)?;
        self.bytes[from as usize..to as usize].fill(0xFF);
        Ok(())
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), RamFlashError> {
        self.check(offset, bytes.len(), Self::WRITE_SIZE as u32)?;
        for (cell, b) in self.bytes[offset as usize..].iter_mut().zip(bytes) {
            *cell &= b;
        }
        Ok(())
    }
}

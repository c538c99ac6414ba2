//! The device configuration in flash: a versioned, CRC-checked record kept in a
//! `sequential-storage` map (wear-levelled, power-fail safe) on any NOR flash.
//!
//! ```text
//!   record = version: u8 │ postcard(DeviceConfig) │ CRC-16/IBM-SDLC of both, little-endian
//! ```
//!
//! [`load`](FlashConfigStore::load) never fails the boot: a missing record, a record of another
//! version, a failed CRC or an unreadable flash all fall back to [`DeviceConfig::DEFAULT`], and the
//! [`ConfigSource`] says which happened (reported to the host as `defaults_in_use`). A stored
//! record that decodes but fails validation is treated as corrupt too.

use embedded_storage_async::nor_flash::NorFlash;
use kerfmeter_protocol::{CRC16, DeviceConfig};
use postcard::experimental::max_size::MaxSize;
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{MapConfig, MapStorage};

/// Version of the record layout; a record of another version is ignored (defaults are used).
pub const CONFIG_RECORD_VERSION: u8 = 1;
/// Map key of the configuration record.
pub const CONFIG_KEY: u8 = 1;
/// Longest record.
pub const RECORD_LEN: usize = 1 + DeviceConfig::POSTCARD_MAX_SIZE + 2;
/// Working buffer for the map: key + value, rounded up to the flash word.
const BUFFER_LEN: usize = (1 + RECORD_LEN + 32).next_multiple_of(32);

/// Where the configuration in use came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigSource {
    /// A valid stored record.
    Stored,
    /// No record yet: defaults.
    Missing,
    /// A record was found but is unusable (another version, bad CRC, invalid values) or the flash
    /// could not be read: defaults.
    Corrupt,
}

impl ConfigSource {
    /// True when the defaults are in use.
    pub fn defaults_in_use(self) -> bool {
        self != ConfigSource::Stored
    }
}

/// Why a record was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RecordError {
    /// Written by another record layout.
    Version(u8),
    /// Checksum mismatch.
    Crc,
    /// The bytes do not decode, or the values fail validation.
    Invalid,
}

/// Encode `config` as a record into `buf`; returns the record.
pub fn encode_record<'b>(config: &DeviceConfig, buf: &'b mut [u8; RECORD_LEN]) -> &'b [u8] {
    buf[0] = CONFIG_RECORD_VERSION;
    let body_len = postcard::to_slice(config, &mut buf[1..RECORD_LEN - 2])
        .expect("the buffer is sized by MaxSize")
        .len();
    let crc = CRC16.checksum(&buf[..1 + body_len]).to_le_bytes();
    buf[1 + body_len..3 + body_len].copy_from_slice(&crc);
    &buf[..3 + body_len]
}

/// Decode and check a record.
pub fn decode_record(record: &[u8]) -> Result<DeviceConfig, RecordError> {
    let (&version, _) = record.split_first().ok_or(RecordError::Invalid)?;
    if record.len() < 3 {
        return Err(RecordError::Invalid);
    }
    let (data, crc) = record.split_at(record.len() - 2);
    if CRC16.checksum(data).to_le_bytes() != crc {
        return Err(RecordError::Crc);
    }
    if version != CONFIG_RECORD_VERSION {
        return Err(RecordError::Version(version));
    }
    let config: DeviceConfig =
        postcard::from_bytes(&data[1..]).map_err(|_| RecordError::Invalid)?;
    config.validate().map_err(|_| RecordError::Invalid)?;
    Ok(config)
}

/// The configuration could not be written; the old record stays valid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StoreError;

/// Persisting the configuration, as the device needs it (synchronous: it is only called while the
/// motor is at rest).
pub trait ConfigPersist {
    /// Store `config`.
    fn save(&mut self, config: &DeviceConfig) -> Result<(), StoreError>;
}

/// No persistence (the configuration lives until reboot).
impl ConfigPersist for () {
    fn save(&mut self, _: &DeviceConfig) -> Result<(), StoreError> {
        Ok(())
    }
}

/// The configuration record in a `sequential-storage` map on flash `F`.
pub struct FlashConfigStore<F: NorFlash> {
    map: MapStorage<u8, F, Cache<Uncached, Uncached, Uncached, u8>>,
}

impl<F: NorFlash> FlashConfigStore<F> {
    /// A store using `range` of `flash` (at least two erase pages, page-aligned).
    pub fn new(flash: F, range: core::ops::Range<u32>) -> Self {
        Self {
            map: MapStorage::new(flash, MapConfig::new(range), Cache::new_uncached()),
        }
    }

    /// The stored configuration, or the defaults and why.
    pub async fn load(&mut self) -> (DeviceConfig, ConfigSource) {
        let mut buf = [0u8; BUFFER_LEN];
        match self.map.fetch_item::<&[u8]>(&mut buf, &CONFIG_KEY).await {
            Ok(Some(record)) => match decode_record(record) {
                Ok(config) => (config, ConfigSource::Stored),
                Err(_) => (DeviceConfig::DEFAULT, ConfigSource::Corrupt),
            },
            Ok(None) => (DeviceConfig::DEFAULT, ConfigSource::Missing),
            Err(_) => (DeviceConfig::DEFAULT, ConfigSource::Corrupt),
        }
    }

    /// Store `config`.
    pub async fn save(
        &mut self,
        config: &DeviceConfig,
    ) -> Result<(), sequential_storage::Error<F::Error>> {
        let mut record = [0u8; RECORD_LEN];
        let record = encode_record(config, &mut record);
        let mut buf = [0u8; BUFFER_LEN];
        self.map.store_item(&mut buf, &CONFIG_KEY, &record).await
    }

    /// Give the flash back.
    pub fn release(self) -> F {
        self.map.destroy().0
    }
}

/// A store whose flash completes every operation immediately (blocking flash behind an async
/// adapter, or the twin's RAM flash) can be driven synchronously.
impl<F: NorFlash> ConfigPersist for FlashConfigStore<F> {
    fn save(&mut self, config: &DeviceConfig) -> Result<(), StoreError> {
        embassy_futures::block_on(FlashConfigStore::save(self, config)).map_err(|_| StoreError)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fakes::flash::RamFlash;

    fn store() -> FlashConfigStore<RamFlash> {
        FlashConfigStore::new(RamFlash::new(4), 0..4 * RamFlash::PAGE)
    }

    #[test]
    fn a_record_round_trips() {
        let mut buf = [0u8; RECORD_LEN];
        let c = DeviceConfig {
            gear_ratio: 30.0,
            ..DeviceConfig::DEFAULT
        };
        assert_eq!(decode_record(encode_record(&c, &mut buf)), Ok(c));
    }

    #[test]
    fn a_flipped_bit_or_another_version_is_rejected() {
        let mut buf = [0u8; RECORD_LEN];
        let record = encode_record(&DeviceConfig::DEFAULT, &mut buf).to_vec();
        for i in 0..record.len() * 8 {
            let mut bad = record.clone();
            bad[i / 8] ^= 1 << (i % 8);
            assert!(decode_record(&bad).is_err(), "bit {i}");
        }
        let mut other = record.clone();
        other[0] = 2;
        let n = other.len();
        let crc = CRC16.checksum(&other[..n - 2]).to_le_bytes();
        other[n - 2..].copy_from_slice(&crc);
        assert_eq!(decode_record(&other), Err(RecordError::Version(2)));
    }

    #[test]
    fn an_empty_flash_gives_the_defaults_and_says_so() {
        let (c, source) = embassy_futures::block_on(store().load());
        assert_eq!(c, DeviceConfig::DEFAULT);
        assert_eq!(source, ConfigSource::Missing);
        assert!(source.defaults_in_use());
    }

    #[test]
    fn a_saved_config_survives_a_reboot() {
        let mut s = store();
        let c = DeviceConfig {
            encoder_zero_raw: 1234,
            ..DeviceConfig::DEFAULT
        };
        ConfigPersist::save(&mut s, &c).unwrap();
        // "Reboot": a new store over the same flash.
        let mut s = FlashConfigStore::new(s.release(), 0..4 * RamFlash::PAGE);
        assert_eq!(
            embassy_futures::block_on(s.load()),
            (c, ConfigSource::Stored)
        );
    }

    #[test]
    fn a_corrupted_record_falls_back_to_defaults() {
        let mut s = store();
        ConfigPersist::save(
            &mut s,
            &DeviceConfig {
                gear_ratio: 50.0,
                ..DeviceConfig::DEFAULT
            },
        )
        .unwrap();
        let mut flash = s.release();
        // Corrupt every byte that holds the stored gear ratio (50.0f32 little-endian).
        let n = flash.corrupt_pattern(&50.0f32.to_le_bytes());
        assert!(n > 0, "the record was found in flash");
        let mut s = FlashConfigStore::new(flash, 0..4 * RamFlash::PAGE);
        let (c, source) = embassy_futures::block_on(s.load());
        assert_eq!(c, DeviceConfig::DEFAULT);
        // sequential-storage's own item CRC may drop the item (Missing) before ours sees it
        // (Corrupt); either way the defaults are in use and the host is told.
        assert!(source.defaults_in_use());
    }
}

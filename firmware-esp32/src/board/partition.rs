//! What the board does at boot with the flash partition that holds its configuration.
//!
//! The configuration lives in the `nvs` data partition of the partition table that espflash
//! writes by default (ESP-IDF's single-app table: `nvs` at 0x9000, 24 KiB). The firmware never
//! uses ESP-IDF's NVS format: the partition holds one [`FlashConfigStore`] and nothing else.
//! Finding the partition in the table is chip code (`board::flash`); what follows is not, and is
//! tested here on a RAM flash.
//!
//! # Policy
//!
//! 1. **No usable partition**: none in the table, the table unreadable, the partition read-only
//!    or encrypted, or not at least two whole erase sectors (the least a `sequential-storage` map
//!    needs). The device runs on the defaults without persistence: a new configuration lasts
//!    until reboot. Nothing is written.
//! 2. **A valid record**: it is used, and the partition is not touched. Our own valid
//!    configuration is never erased.
//! 3. **No valid record** (none, a record of another layout version, a failed CRC, values that
//!    fail validation, or a map the store cannot read): the defaults are used, and
//!    - a blank partition (all 0xFF) is left as it is;
//!    - any other content is erased, the whole partition. It is data this firmware cannot use:
//!      typically ESP-IDF NVS pages left by a board's factory firmware, which the store would
//!      take for free space; or a record of ours that is corrupt, which is lost either way. After the erase the next `SetConfig`
//!      persists.
//! 4. **The partition cannot be read or erased** while doing so: defaults, no persistence.
//!
//! The store's source ([`ConfigSource`]) is reported unchanged in every case, so that the host
//! sees `defaults_in_use` whenever the defaults are in use.

use core::fmt;
use core::ops::Range;

use embedded_storage_async::nor_flash::NorFlash;
use kerfmeter_protocol::DeviceConfig;

use crate::config_store::{ConfigPersist, ConfigSource, FlashConfigStore, StoreError};

/// Why no flash partition can hold the configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PartitionError {
    /// The partition table could not be read.
    TableUnreadable,
    /// The table has no `nvs` data partition.
    NotFound,
    /// The partition is read-only or encrypted.
    ReadOnlyOrEncrypted,
    /// The partition is not at least two whole erase sectors.
    NotTwoWholeSectors,
}

impl fmt::Display for PartitionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            PartitionError::TableUnreadable => "partition table unreadable",
            PartitionError::NotFound => "no `nvs` partition in the partition table",
            PartitionError::ReadOnlyOrEncrypted => "the `nvs` partition is read-only or encrypted",
            PartitionError::NotTwoWholeSectors => {
                "the `nvs` partition is not at least two whole flash sectors"
            }
        })
    }
}

/// A partition as the partition table describes it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PartitionEntry {
    /// Start, bytes from the start of the flash.
    pub offset: u32,
    /// Length, bytes.
    pub len: u32,
    /// Flagged read-only.
    pub read_only: bool,
    /// Flagged encrypted.
    pub encrypted: bool,
}

impl PartitionEntry {
    /// The flash range the configuration store may use, on a flash whose erase sector is
    /// `sector` bytes: the whole partition, if it is writable, unencrypted and at least two whole
    /// sectors (policy step 1).
    pub fn config_range(&self, sector: u32) -> Result<Range<u32>, PartitionError> {
        if self.read_only || self.encrypted {
            return Err(PartitionError::ReadOnlyOrEncrypted);
        }
        let range = self.offset..self.offset.saturating_add(self.len);
        if !range.start.is_multiple_of(sector)
            || !range.end.is_multiple_of(sector)
            || range.len() < 2 * sector as usize
        {
            return Err(PartitionError::NotTwoWholeSectors);
        }
        Ok(range)
    }
}

/// Where a new configuration is persisted.
pub enum ConfigStorage<F: NorFlash> {
    /// In the flash partition.
    Flash(FlashConfigStore<F>),
    /// Nowhere: the configuration lasts until reboot.
    RamOnly,
}

impl<F: NorFlash> ConfigPersist for ConfigStorage<F> {
    fn save(&mut self, config: &DeviceConfig) -> Result<(), StoreError> {
        match self {
            // `FlashConfigStore`'s synchronous `save` needs a flash that completes every
            // operation at once (the board's blocking flash behind an async adapter).
            ConfigStorage::Flash(store) => ConfigPersist::save(store, config),
            ConfigStorage::RamOnly => ConfigPersist::save(&mut (), config),
        }
    }
}

/// What opening the partition did, for the boot log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PartitionOutcome {
    /// No usable partition (policy step 1).
    Unusable(PartitionError),
    /// A valid record was found; the partition was not touched (step 2).
    RecordKept,
    /// No valid record, and the partition is blank (step 3).
    Blank,
    /// No valid record, and the partition's content was erased (step 3).
    Erased,
    /// The partition could not be read or erased; no persistence (step 4).
    Failed,
}

/// The boot log's line, after "configuration flash: ".
impl fmt::Display for PartitionOutcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PartitionOutcome::Unusable(why) => {
                write!(f, "{why}; configuration lasts until reboot")
            }
            PartitionOutcome::RecordKept => f.write_str("valid record"),
            PartitionOutcome::Blank => f.write_str("no record, blank"),
            PartitionOutcome::Erased => f.write_str("no valid record, foreign data erased"),
            PartitionOutcome::Failed => {
                f.write_str("unreadable or not erasable; configuration lasts until reboot")
            }
        }
    }
}

/// The configuration to boot with, where new ones go, and what was done to get there.
pub struct OpenedConfig<F: NorFlash> {
    /// The configuration in use.
    pub config: DeviceConfig,
    /// Where it came from.
    pub source: ConfigSource,
    /// Where a new one is persisted.
    pub storage: ConfigStorage<F>,
    /// What happened to the partition.
    pub outcome: PartitionOutcome,
}

impl<F: NorFlash> OpenedConfig<F> {
    /// No usable partition: the defaults, no persistence (policy step 1).
    pub fn without_partition(why: PartitionError) -> Self {
        Self {
            config: DeviceConfig::DEFAULT,
            source: ConfigSource::Missing,
            storage: ConfigStorage::RamOnly,
            outcome: PartitionOutcome::Unusable(why),
        }
    }
}

/// Load the configuration from `range` of `flash`, applying the policy in the module docs.
pub async fn open_config_partition<F: NorFlash>(flash: F, range: Range<u32>) -> OpenedConfig<F> {
    let mut store = FlashConfigStore::new(flash, range.clone());
    let (config, source) = store.load().await;
    let opened = |storage, outcome| OpenedConfig {
        config,
        source,
        storage,
        outcome,
    };
    if !source.defaults_in_use() {
        return opened(ConfigStorage::Flash(store), PartitionOutcome::RecordKept);
    }
    let mut flash = store.release();
    let outcome = match erase_if_not_blank(&mut flash, range.clone()).await {
        Ok(false) => PartitionOutcome::Blank,
        Ok(true) => PartitionOutcome::Erased,
        Err(()) => return opened(ConfigStorage::RamOnly, PartitionOutcome::Failed),
    };
    opened(
        ConfigStorage::Flash(FlashConfigStore::new(flash, range)),
        outcome,
    )
}

/// Erase `range` unless it is blank (all 0xFF). True when it was erased.
async fn erase_if_not_blank<F: NorFlash>(flash: &mut F, range: Range<u32>) -> Result<bool, ()> {
    /// Word-aligned, so that the ESP32's flash driver reads straight into it.
    #[repr(align(4))]
    struct Block([u8; 256]);
    let mut block = Block([0; 256]);
    let mut blank = true;
    for offset in range.clone().step_by(block.0.len()) {
        flash.read(offset, &mut block.0).await.map_err(|_| ())?;
        if block.0.iter().any(|&b| b != 0xFF) {
            blank = false;
            break;
        }
    }
    if blank {
        return Ok(false);
    }
    flash.erase(range.start, range.end).await.map_err(|_| ())?;
    Ok(true)
}

#[cfg(test)]
mod tests {
    use embassy_futures::block_on;
    use embedded_storage_async::nor_flash::{ErrorType, ReadNorFlash};

    use super::*;
    use crate::fakes::flash::RamFlash;

    const PAGE: u32 = RamFlash::PAGE;
    /// The partition: pages 1..4 of a 6-page flash, with a page of other data on each side.
    const RANGE: Range<u32> = PAGE..4 * PAGE;

    /// A 6-page flash whose pages outside [`RANGE`] hold other data.
    fn flash() -> RamFlash {
        let mut flash = RamFlash::new(6);
        block_on(async {
            flash.write(0, &[0x11; 64]).await.unwrap();
            flash.write(5 * PAGE, &[0x22; 64]).await.unwrap();
        });
        flash
    }

    fn bytes(flash: &mut RamFlash, range: Range<u32>) -> Vec<u8> {
        let mut out = vec![0; range.len()];
        block_on(flash.read(range.start, &mut out)).unwrap();
        out
    }

    fn with_config(gear_ratio: f32) -> RamFlash {
        let mut store = FlashConfigStore::new(flash(), RANGE);
        let config = DeviceConfig {
            gear_ratio,
            ..DeviceConfig::DEFAULT
        };
        ConfigPersist::save(&mut store, &config).unwrap();
        store.release()
    }

    fn storage_flash(opened: OpenedConfig<RamFlash>) -> RamFlash {
        match opened.storage {
            ConfigStorage::Flash(store) => store.release(),
            ConfigStorage::RamOnly => panic!("no persistence"),
        }
    }

    /// Save a configuration through what `opened` offers, then boot again: it must be stored.
    fn assert_next_save_persists(opened: OpenedConfig<RamFlash>) {
        let mut storage = opened.storage;
        let config = DeviceConfig {
            encoder_zero_raw: 4321,
            ..DeviceConfig::DEFAULT
        };
        ConfigPersist::save(&mut storage, &config).unwrap();
        let ConfigStorage::Flash(store) = storage else {
            panic!("no persistence");
        };
        let reopened = block_on(open_config_partition(store.release(), RANGE));
        assert_eq!(reopened.config, config);
        assert_eq!(reopened.source, ConfigSource::Stored);
        assert_eq!(reopened.outcome, PartitionOutcome::RecordKept);
    }

    /// Pages as a factory firmware's ESP-IDF NVS leaves them: an active page header (state word
    /// 0xFFFF_FFFE, sequence number, version) and a few entries, the rest blank.
    fn foreign_flash() -> RamFlash {
        let mut flash = flash();
        block_on(async {
            for (i, page) in RANGE.step_by(PAGE as usize).enumerate() {
                let mut header = [0xFFu8; 32];
                header[..4].copy_from_slice(&0xFFFF_FFFEu32.to_le_bytes());
                header[4..8].copy_from_slice(&(i as u32).to_le_bytes());
                header[8] = 0xFE;
                flash.write(page, &header).await.unwrap();
                flash
                    .write(page + 64, b"phy_init\0\0\0\0wifi.cfg")
                    .await
                    .unwrap();
            }
        });
        flash
    }

    #[test]
    fn a_valid_record_is_used_and_nothing_is_written() {
        let mut flash = with_config(30.0);
        let before = bytes(&mut flash, 0..6 * PAGE);
        let opened = block_on(open_config_partition(flash, RANGE));
        assert_eq!(opened.config.gear_ratio, 30.0);
        assert_eq!(opened.source, ConfigSource::Stored);
        assert_eq!(opened.outcome, PartitionOutcome::RecordKept);
        let mut flash = storage_flash(opened);
        assert_eq!(bytes(&mut flash, 0..6 * PAGE), before);
    }

    #[test]
    fn a_blank_partition_gives_the_defaults_and_stays_blank() {
        let mut flash = flash();
        let before = bytes(&mut flash, 0..6 * PAGE);
        let opened = block_on(open_config_partition(flash, RANGE));
        assert_eq!(opened.config, DeviceConfig::DEFAULT);
        assert_eq!(opened.source, ConfigSource::Missing);
        assert_eq!(opened.outcome, PartitionOutcome::Blank);
        let mut flash = storage_flash(opened);
        assert_eq!(bytes(&mut flash, 0..6 * PAGE), before);
        let opened = block_on(open_config_partition(flash, RANGE));
        assert_next_save_persists(opened);
    }

    #[test]
    fn a_foreign_partition_is_erased_and_only_the_partition() {
        let flash = foreign_flash();
        let opened = block_on(open_config_partition(flash, RANGE));
        assert_eq!(opened.config, DeviceConfig::DEFAULT);
        assert!(opened.source.defaults_in_use());
        assert_eq!(opened.outcome, PartitionOutcome::Erased);
        let mut flash = storage_flash(opened);
        assert!(bytes(&mut flash, RANGE).iter().all(|&b| b == 0xFF));
        assert_eq!(bytes(&mut flash, 0..64), [0x11; 64]);
        assert_eq!(bytes(&mut flash, 5 * PAGE..5 * PAGE + 64), [0x22; 64]);
    }

    #[test]
    fn after_a_foreign_partition_is_erased_the_next_save_persists() {
        let opened = block_on(open_config_partition(foreign_flash(), RANGE));
        assert_next_save_persists(opened);
    }

    #[test]
    fn a_corrupt_record_gives_the_defaults_and_is_erased() {
        let mut flash = with_config(50.0);
        // Corrupt every byte that holds the stored gear ratio (50.0f32 little-endian).
        assert!(flash.corrupt_pattern(&50.0f32.to_le_bytes()) > 0);
        let opened = block_on(open_config_partition(flash, RANGE));
        assert_eq!(opened.config, DeviceConfig::DEFAULT);
        assert!(opened.source.defaults_in_use());
        assert_eq!(opened.outcome, PartitionOutcome::Erased);
        assert_next_save_persists(opened);
    }

    /// A flash that reads and writes, but fails every erase.
    struct NoErase(RamFlash);

    impl ErrorType for NoErase {
        type Error = <RamFlash as ErrorType>::Error;
    }

    impl ReadNorFlash for NoErase {
        const READ_SIZE: usize = RamFlash::READ_SIZE;
        async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), Self::Error> {
            self.0.read(offset, bytes).await
        }
        fn capacity(&self) -> usize {
            self.0.capacity()
        }
    }

    impl NorFlash for NoErase {
        const WRITE_SIZE: usize = RamFlash::WRITE_SIZE;
        const ERASE_SIZE: usize = RamFlash::ERASE_SIZE;
        async fn erase(&mut self, from: u32, to: u32) -> Result<(), Self::Error> {
            // Out of bounds: the RAM flash's own error for it.
            self.0.erase(to, from.wrapping_sub(1)).await
        }
        async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Self::Error> {
            self.0.write(offset, bytes).await
        }
    }

    #[test]
    fn a_partition_that_cannot_be_erased_leaves_no_persistence() {
        let opened = block_on(open_config_partition(NoErase(foreign_flash()), RANGE));
        assert_eq!(opened.config, DeviceConfig::DEFAULT);
        assert_eq!(opened.outcome, PartitionOutcome::Failed);
        assert!(matches!(opened.storage, ConfigStorage::RamOnly));
        // A save then succeeds, and lasts until reboot only.
        let mut storage = opened.storage;
        assert_eq!(
            ConfigPersist::save(&mut storage, &DeviceConfig::DEFAULT),
            Ok(())
        );
    }

    #[test]
    fn without_a_partition_the_defaults_are_used_without_persistence() {
        let opened = OpenedConfig::<RamFlash>::without_partition(PartitionError::NotFound);
        assert_eq!(opened.config, DeviceConfig::DEFAULT);
        assert_eq!(opened.source, ConfigSource::Missing);
        assert_eq!(
            opened.outcome,
            PartitionOutcome::Unusable(PartitionError::NotFound)
        );
        assert!(matches!(opened.storage, ConfigStorage::RamOnly));
    }

    #[test]
    fn only_a_writable_partition_of_two_whole_sectors_is_used() {
        // ESP-IDF's default table: `nvs` at 0x9000, 24 KiB.
        let nvs = PartitionEntry {
            offset: 0x9000,
            len: 0x6000,
            read_only: false,
            encrypted: false,
        };
        assert_eq!(nvs.config_range(PAGE), Ok(0x9000..0xF000));
        let cases = [
            (
                0x9000,
                0x1000,
                false,
                false,
                PartitionError::NotTwoWholeSectors,
            ),
            (
                0x9100,
                0x6000,
                false,
                false,
                PartitionError::NotTwoWholeSectors,
            ),
            (
                0x9000,
                0x2800,
                false,
                false,
                PartitionError::NotTwoWholeSectors,
            ),
            (
                0x9000,
                0x6000,
                true,
                false,
                PartitionError::ReadOnlyOrEncrypted,
            ),
            (
                0x9000,
                0x6000,
                false,
                true,
                PartitionError::ReadOnlyOrEncrypted,
            ),
        ];
        for (offset, len, read_only, encrypted, error) in cases {
            let entry = PartitionEntry {
                offset,
                len,
                read_only,
                encrypted,
            };
            assert_eq!(entry.config_range(PAGE), Err(error), "{entry:?}");
        }
    }
}

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
//! The rule is: **a stored calibration is never erased or saved over by the firmware on its
//! own; only data that is not this firmware's is erased.**
//!
//! 1. **No usable partition**: none in the table, the table unreadable, the partition read-only
//!    or encrypted, or not at least two whole erase sectors (the least a `sequential-storage` map
//!    needs). The device runs on the defaults without persistence: a new configuration is
//!    applied but not saved ([`Persisted::No`]) and lasts until reboot. Nothing is written.
//! 2. **A valid record** of this firmware's version, or of an older one (migrated on reading,
//!    see [`crate::config_store`]): it is used, and the partition is not touched.
//! 3. **A record of a newer version** (a firmware downgrade): not understood, so the defaults
//!    are used and reported, and the record is kept. New configurations are applied but not
//!    saved ([`ConfigStorage::Protected`]): a `SetConfig` alone never replaces it. The newer
//!    firmware reads it again; to give it up and store this version's, erase the partition
//!    explicitly (`espflash erase-region 0x9000 0x6000` for the default table's `nvs`). The
//!    protocol has no request for it: an erase is a deliberate act at the bench, not something
//!    a host tool does by accident with a `SetConfig` built from the defaults it was shown.
//! 4. **No usable record** (none, a damaged one, or a map the store cannot read): the defaults
//!    are used, and what is in the partition decides:
//!    - **ours**: at least one sector starts with `sequential-storage`'s page marker, a first
//!      word with at least half of its 32 bits cleared (the map clears the whole word when it
//!      starts writing a page). It is left as it is: the map repairs torn pages itself and skips
//!      damaged items, and the next `SetConfig` appends a new record. A record this firmware
//!      cannot read is never a reason to erase.
//!    - **blank** (all 0xFF): left as it is.
//!    - **anything else is not ours** and is erased, the whole partition: typically ESP-IDF NVS
//!      pages left by a board's factory firmware (their page-state words 0xFFFF_FFFE/FC/F8/F0
//!      clear at most 4 bits), which the store would take for free space. The next `SetConfig`
//!      then persists. Its blind spot: a page that ESP-IDF marked invalid (state word zero)
//!      passes for ours; the map skips what it cannot read there, and saves still persist.
//! 5. **The partition cannot be read or erased** while doing so: defaults, no persistence.
//!
//! The store's source ([`ConfigSource`]) is reported unchanged in every case, so that the host
//! sees `defaults_in_use` whenever the defaults are in use.

use core::fmt;
use core::ops::Range;

use embedded_storage_async::nor_flash::NorFlash;
use kerfmeter_protocol::DeviceConfig;

use crate::config_store::{ConfigPersist, ConfigSource, FlashConfigStore, Persisted, StoreError};

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
    /// Nowhere: the partition holds a newer firmware's record, kept unchanged (policy step 3).
    /// The configuration lasts until reboot.
    Protected(FlashConfigStore<F>),
    /// Nowhere: the configuration lasts until reboot.
    RamOnly,
}

impl<F: NorFlash> ConfigStorage<F> {
    /// True when a new configuration is saved to flash.
    pub fn persists(&self) -> bool {
        matches!(self, ConfigStorage::Flash(_))
    }

    /// Give the flash back, if there is one (a simulated reboot keeps it).
    pub fn into_flash(self) -> Option<F> {
        match self {
            ConfigStorage::Flash(store) | ConfigStorage::Protected(store) => Some(store.release()),
            ConfigStorage::RamOnly => None,
        }
    }
}

impl<F: NorFlash> ConfigPersist for ConfigStorage<F> {
    fn save(&mut self, config: &DeviceConfig) -> Result<Persisted, StoreError> {
        match self {
            // `FlashConfigStore`'s synchronous `save` needs a flash that completes every
            // operation at once (the board's blocking flash behind an async adapter).
            ConfigStorage::Flash(store) => ConfigPersist::save(store, config),
            ConfigStorage::Protected(_) | ConfigStorage::RamOnly => Ok(Persisted::No),
        }
    }
}

/// What opening the partition did, for the boot log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PartitionOutcome {
    /// No usable partition (policy step 1).
    Unusable(PartitionError),
    /// A valid record (maybe of an older version) was found; the partition was not touched
    /// (step 2).
    RecordKept,
    /// A newer firmware's record was found; it is kept and not saved over (step 3).
    NewerRecordKept,
    /// No usable record in a map of ours; it is kept as it is (step 4).
    MapKept,
    /// No record, and the partition is blank (step 4).
    Blank,
    /// The partition held data that is not ours; it was erased (step 4).
    Erased,
    /// The partition could not be read or erased; no persistence (step 5).
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
            PartitionOutcome::NewerRecordKept => f.write_str(
                "record of a newer firmware, kept; configuration lasts until reboot \
                 (erase the partition to replace it)",
            ),
            PartitionOutcome::MapKept => f.write_str("no usable record; map kept"),
            PartitionOutcome::Blank => f.write_str("no record, blank"),
            PartitionOutcome::Erased => f.write_str("foreign data erased"),
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
    match source {
        ConfigSource::Stored | ConfigSource::Migrated { .. } => {
            return opened(ConfigStorage::Flash(store), PartitionOutcome::RecordKept);
        }
        ConfigSource::Newer { .. } => {
            return opened(
                ConfigStorage::Protected(store),
                PartitionOutcome::NewerRecordKept,
            );
        }
        ConfigSource::Missing | ConfigSource::Corrupt => {}
    }
    let mut flash = store.release();
    let outcome = match classify(&mut flash, range.clone()).await {
        Ok(Content::Ours) => PartitionOutcome::MapKept,
        Ok(Content::Blank) => PartitionOutcome::Blank,
        Ok(Content::Foreign) => match flash.erase(range.start, range.end).await {
            Ok(()) => PartitionOutcome::Erased,
            Err(_) => return opened(ConfigStorage::RamOnly, PartitionOutcome::Failed),
        },
        Err(()) => return opened(ConfigStorage::RamOnly, PartitionOutcome::Failed),
    };
    opened(
        ConfigStorage::Flash(FlashConfigStore::new(flash, range)),
        outcome,
    )
}

/// Whose data a partition without a usable record holds (policy step 4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Content {
    /// A `sequential-storage` map: some sector starts with its page marker.
    Ours,
    /// All 0xFF.
    Blank,
    /// Neither.
    Foreign,
}

/// Classify `range` of `flash`, one erase sector at a time.
async fn classify<F: NorFlash>(flash: &mut F, range: Range<u32>) -> Result<Content, ()> {
    /// Word-aligned, so that the ESP32's flash driver reads straight into it.
    #[repr(align(4))]
    struct Block([u8; 256]);
    let mut block = Block([0; 256]);
    let mut blank = true;
    for sector in range.clone().step_by(F::ERASE_SIZE) {
        for offset in (sector..sector + F::ERASE_SIZE as u32).step_by(block.0.len()) {
            flash.read(offset, &mut block.0).await.map_err(|_| ())?;
            if offset == sector && is_page_marker(&block.0[..4]) {
                return Ok(Content::Ours);
            }
            blank &= block.0.iter().all(|&b| b == 0xFF);
        }
    }
    Ok(if blank {
        Content::Blank
    } else {
        Content::Foreign
    })
}

/// True for a sector's first word as `sequential-storage` marks a page it writes (all bits
/// cleared), allowing for up to half of them lost.
fn is_page_marker(word: &[u8]) -> bool {
    word.iter().map(|b| b.count_zeros()).sum::<u32>() >= 16
}

#[cfg(test)]
mod tests {
    use embassy_futures::block_on;
    use embedded_storage_async::nor_flash::{ErrorType, ReadNorFlash};

    use super::*;
    use crate::config_store::tests::{FIXTURE_CONFIG, FIXTURE_RECORD_V1, fixture_flash};
    use crate::config_store::{MAX_RECORD_LEN, encode_record};
    use crate::fakes::flash::{FlashClock, RamFlash};

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
        opened.storage.into_flash().expect("no flash")
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
    fn a_corrupt_record_gives_the_defaults_and_is_kept() {
        let mut flash = with_config(50.0);
        // Corrupt every byte that holds the stored gear ratio (50.0f32 little-endian).
        assert!(flash.corrupt_pattern(&50.0f32.to_le_bytes()) > 0);
        let before = bytes(&mut flash, 0..6 * PAGE);
        let opened = block_on(open_config_partition(flash, RANGE));
        assert_eq!(opened.config, DeviceConfig::DEFAULT);
        assert!(opened.source.defaults_in_use());
        assert_eq!(opened.outcome, PartitionOutcome::MapKept);
        assert!(opened.storage.persists());
        let mut flash = storage_flash(opened);
        assert_eq!(bytes(&mut flash, 0..6 * PAGE), before, "nothing erased");
        assert_next_save_persists(block_on(open_config_partition(flash, RANGE)));
    }

    #[test]
    fn a_record_that_fails_its_own_crc_is_kept() {
        // An item the map reads, whose record is damaged: ours, so not erased.
        let mut store = FlashConfigStore::new(flash(), RANGE);
        let mut buf = [0u8; MAX_RECORD_LEN];
        let mut record = encode_record(&DeviceConfig::DEFAULT, &mut buf).to_vec();
        *record.last_mut().unwrap() ^= 1;
        block_on(store.store_record(&record)).unwrap();
        let mut flash = store.release();
        let before = bytes(&mut flash, 0..6 * PAGE);
        let opened = block_on(open_config_partition(flash, RANGE));
        assert_eq!(opened.source, ConfigSource::Corrupt);
        assert_eq!(opened.outcome, PartitionOutcome::MapKept);
        let mut flash = storage_flash(opened);
        assert_eq!(bytes(&mut flash, 0..6 * PAGE), before);
    }

    #[test]
    fn the_old_firmwares_partition_loads_untouched() {
        let mut flash = fixture_flash(6, PAGE);
        let before = bytes(&mut flash, 0..6 * PAGE);
        let opened = block_on(open_config_partition(flash, RANGE));
        assert_eq!(opened.config, FIXTURE_CONFIG);
        assert_eq!(opened.source, ConfigSource::Stored);
        assert_eq!(opened.outcome, PartitionOutcome::RecordKept);
        let mut flash = storage_flash(opened);
        assert_eq!(bytes(&mut flash, 0..6 * PAGE), before);
    }

    /// A partition holding a record of version 9 (a newer firmware's).
    fn newer_flash() -> RamFlash {
        let mut record = FIXTURE_RECORD_V1.to_vec();
        record[0] = 9;
        let n = record.len();
        let crc = kerfmeter_protocol::CRC16
            .checksum(&record[..n - 2])
            .to_le_bytes();
        record[n - 2..].copy_from_slice(&crc);
        let mut store = FlashConfigStore::new(flash(), RANGE);
        block_on(store.store_record(&record)).unwrap();
        store.release()
    }

    #[test]
    fn a_newer_firmwares_record_is_kept_and_not_saved_over() {
        let mut flash = newer_flash();
        let before = bytes(&mut flash, 0..6 * PAGE);
        let opened = block_on(open_config_partition(flash, RANGE));
        assert_eq!(opened.config, DeviceConfig::DEFAULT);
        assert_eq!(opened.source, ConfigSource::Newer { version: Some(9) });
        assert!(opened.source.defaults_in_use());
        assert_eq!(opened.outcome, PartitionOutcome::NewerRecordKept);
        assert!(!opened.storage.persists());
        // A new configuration is applied but not saved.
        let mut storage = opened.storage;
        let config = DeviceConfig {
            gear_ratio: 40.0,
            ..DeviceConfig::DEFAULT
        };
        assert_eq!(
            ConfigPersist::save(&mut storage, &config),
            Ok(Persisted::No)
        );
        let mut flash = storage.into_flash().unwrap();
        assert_eq!(bytes(&mut flash, 0..6 * PAGE), before, "not written");
        let reopened = block_on(open_config_partition(flash, RANGE));
        assert_eq!(reopened.source, ConfigSource::Newer { version: Some(9) });
    }

    #[test]
    fn nvs_pages_marked_invalid_pass_for_ours_and_saves_still_persist() {
        // The rule's blind spot: ESP-IDF marks a page it gave up on with a zero state word,
        // which reads as the map's page marker. The map then skips what it cannot read.
        let mut flash = flash();
        block_on(async {
            for page in RANGE.step_by(PAGE as usize) {
                flash.write(page, &[0; 4]).await.unwrap();
                flash
                    .write(page + 64, b"phy_init\0\0\0\0wifi.cfg")
                    .await
                    .unwrap();
            }
        });
        let opened = block_on(open_config_partition(flash, RANGE));
        assert_eq!(opened.outcome, PartitionOutcome::MapKept);
        assert_next_save_persists(opened);
    }

    #[test]
    fn random_bytes_without_a_page_marker_are_not_ours_and_are_erased() {
        let mut flash = flash();
        let mut rng = crate::fakes::rng::Rng::new(5);
        block_on(async {
            for offset in RANGE.step_by(4) {
                // Bytes with few bits cleared, as in a foreign format's headers and free space.
                let word = (rng.next_u64() as u32) | 0xFEFE_FEFE;
                flash.write(offset, &word.to_le_bytes()).await.unwrap();
            }
        });
        let opened = block_on(open_config_partition(flash, RANGE));
        assert_eq!(opened.outcome, PartitionOutcome::Erased);
        let mut flash = storage_flash(opened);
        assert!(bytes(&mut flash, RANGE).iter().all(|&b| b == 0xFF));
    }

    #[test]
    fn the_page_marker_rule() {
        assert!(is_page_marker(&[0, 0, 0, 0]));
        // Up to half the bits lost.
        assert!(is_page_marker(&[0xFF, 0xFF, 0, 0]));
        assert!(!is_page_marker(&[0xFF, 0xFF, 0xFF, 0x7F]));
        // ESP-IDF NVS page states: active, full, freeing, corrupt.
        for state in [0xFFFF_FFFEu32, 0xFFFF_FFFC, 0xFFFF_FFF8, 0xFFFF_FFF0] {
            assert!(!is_page_marker(&state.to_le_bytes()), "{state:#x}");
        }
    }

    /// A sector erase and a program page take as long as on the ESP32-C3's flash, µs.
    const ERASE_US: u64 = 400_000;
    const WRITE_PAGE_US: u64 = 3_000;

    /// What saving configurations one after the other on a timed flash came to, at the first
    /// save that `erases` (or not) a sector, counted from save `skip` on.
    struct Before {
        /// The flash just before that save.
        flash: RamFlash,
        /// The configuration saved before it.
        stored: DeviceConfig,
        /// The configuration it saves.
        saving: DeviceConfig,
        /// How long it takes, µs.
        takes_us: u64,
    }

    fn numbered(n: u16) -> DeviceConfig {
        DeviceConfig {
            encoder_zero_raw: n + 1,
            ..DeviceConfig::DEFAULT
        }
    }

    fn before_a_save(skip: u16, erases: bool) -> Before {
        let clock = FlashClock::new(ERASE_US, WRITE_PAGE_US, 1);
        let mut store = FlashConfigStore::new(flash().with_clock(clock.clone()), RANGE);
        for n in 0..2000 {
            let flash = store.release();
            let snapshot = flash.clone().with_clock(FlashClock::default());
            store = FlashConfigStore::new(flash, RANGE);
            let (erased, _) = (clock.erases(), clock.take_spent_us());
            ConfigPersist::save(&mut store, &numbered(n)).unwrap();
            if n >= skip && (clock.erases() > erased) == erases {
                return Before {
                    flash: snapshot,
                    stored: numbered(n - 1),
                    saving: numbered(n),
                    takes_us: clock.take_spent_us(),
                };
            }
        }
        panic!("no such save");
    }

    /// Cut the power `budget_us` into `before`'s save, then boot: the configuration must be
    /// the one stored before, or the new one, and the next save must persist. Whether the save
    /// was cut, and whether the new configuration loaded.
    fn assert_a_cut_save_loses_nothing(before: &Before, budget_us: u64, seed: u64) -> (bool, bool) {
        let clock = FlashClock::new(ERASE_US, WRITE_PAGE_US, seed);
        clock.set_budget_us(Some(budget_us));
        let mut store =
            FlashConfigStore::new(before.flash.clone().with_clock(clock.clone()), RANGE);
        let saved = ConfigPersist::save(&mut store, &before.saving).is_ok();
        assert!(saved || clock.is_cut(), "cut at {budget_us} µs");
        clock.power_on();
        let opened = block_on(open_config_partition(store.release(), RANGE));
        assert_eq!(opened.source, ConfigSource::Stored, "cut at {budget_us} µs");
        assert!(
            opened.config == before.stored || opened.config == before.saving,
            "cut at {budget_us} µs: {:?}",
            opened.config
        );
        if saved {
            assert_eq!(opened.config, before.saving);
        }
        let outcome = (!saved, opened.config == before.saving);
        assert_next_save_persists(opened);
        outcome
    }

    /// Run `cuts` ((budget, seed) pairs) on `before`: some must tear the save, and both the
    /// old and the new configuration must come out of some.
    fn assert_cuts_lose_nothing(before: &Before, cuts: impl Iterator<Item = (u64, u64)>) {
        let outcomes: Vec<_> = cuts
            .map(|(budget_us, seed)| assert_a_cut_save_loses_nothing(before, budget_us, seed))
            .collect();
        let torn = outcomes.iter().filter(|o| o.0).count();
        assert!(
            torn >= outcomes.len() / 2,
            "{torn} of {} torn",
            outcomes.len()
        );
        assert!(
            outcomes.iter().any(|o| o.0 && !o.1),
            "some keep the old one"
        );
        assert!(outcomes.iter().any(|o| o.1), "some load the new one");
    }

    #[test]
    fn a_save_torn_anywhere_in_its_erase_leaves_the_last_good_record() {
        let before = before_a_save(1, true);
        assert!(before.takes_us >= ERASE_US, "{} µs", before.takes_us);
        // Early and late in the first erase (its start is where a torn sector looks least like
        // the map's), then across the whole save.
        let budgets = [
            0,
            1,
            50,
            200,
            1_000,
            5_000,
            ERASE_US - 1,
            ERASE_US,
            ERASE_US + 1,
        ];
        let sweep = (0..=64).map(|i| before.takes_us * i / 64);
        let cuts = budgets.into_iter().chain(sweep).zip(0..);
        assert_cuts_lose_nothing(&before, cuts);
    }

    #[test]
    fn a_save_torn_anywhere_in_its_write_leaves_the_last_good_record() {
        let before = before_a_save(5, false);
        assert!(before.takes_us > 0);
        let cuts = (0..=before.takes_us).step_by(50).map(|b| (b, b));
        assert_cuts_lose_nothing(&before, cuts);
    }

    #[test]
    fn without_a_partition_a_save_is_not_claimed_persisted() {
        let mut storage = ConfigStorage::<RamFlash>::RamOnly;
        assert!(!storage.persists());
        assert_eq!(
            ConfigPersist::save(&mut storage, &DeviceConfig::DEFAULT),
            Ok(Persisted::No)
        );
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
            Ok(Persisted::No)
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

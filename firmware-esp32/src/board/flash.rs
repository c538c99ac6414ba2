//! The configuration's flash on the chip: the SPI flash through esp-storage, and the `nvs` data
//! partition found in the partition table. What is then done with the partition is the
//! chip-independent policy in [`super::partition`].
//!
//! Every erase and write runs in its own watchdog window ([`WatchdogFlash`] over the board's
//! MWDT): esp-storage runs them with interrupts off and the core stalled, a sector erase for up
//! to 400 ms, far past the 50 ms the watchdog allows the control loop.

use core::ops::Range;

use embassy_embedded_hal::adapter::BlockingAsync;
use esp_bootloader_esp_idf::partitions;
use esp_hal::peripherals::FLASH;
use esp_storage::FlashStorage;

use super::partition::{PartitionEntry, PartitionError};
use super::watchdog::BoardWatchdog;
use crate::watchdog::WatchdogFlash;

/// The flash behind the configuration store: blocking, behind an async adapter, so that every
/// operation completes at once (as `FlashConfigStore`'s synchronous save requires), each erase
/// and write in its own watchdog window.
pub type ConfigFlash = WatchdogFlash<BlockingAsync<FlashStorage<'static>>, BoardWatchdog>;

/// The flash, and the range of its `nvs` partition that the configuration store may use.
pub fn config_partition(
    flash: FLASH<'static>,
) -> Result<(ConfigFlash, Range<u32>), PartitionError> {
    let mut flash = FlashStorage::new(flash);
    let range = nvs_partition(&mut flash)?.config_range(FlashStorage::SECTOR_SIZE)?;
    Ok((
        WatchdogFlash::new(BlockingAsync::new(flash), BoardWatchdog),
        range,
    ))
}

/// The partition table's `nvs` data partition.
///
/// Matched by raw type and subtype (data, nvs) and label rather than with the crate's typed
/// lookup, which panics on a subtype it does not know.
fn nvs_partition(flash: &mut FlashStorage<'static>) -> Result<PartitionEntry, PartitionError> {
    /// Partition type "data", subtype "nvs" (ESP-IDF's numbering).
    const DATA: u8 = 0x01;
    const NVS: u8 = 0x02;
    let mut table = [0u8; partitions::PARTITION_TABLE_MAX_LEN];
    let table = partitions::read_partition_table(flash, &mut table)
        .map_err(|_| PartitionError::TableUnreadable)?;
    let nvs = table
        .iter()
        .find(|e| e.raw_type() == DATA && e.raw_subtype() == NVS && e.label_as_str() == "nvs")
        .ok_or(PartitionError::NotFound)?;
    Ok(PartitionEntry {
        offset: nvs.offset(),
        len: nvs.len(),
        read_only: nvs.is_read_only(),
        encrypted: nvs.is_encrypted(),
    })
}

//! The AS5048A on the chip: SPI2 in mode 1 at 10 MHz, blocking (a transfer of two bytes takes a
//! few µs, less than handing it to DMA would), with the chip select as a plain GPIO that idles
//! high; then the library's [`As5048a`] driver over it.

use embedded_hal_bus::spi::ExclusiveDevice;
use esp_hal::{
    Blocking,
    delay::Delay,
    gpio::{Level, Output, OutputConfig},
    peripherals::SPI2,
    spi::{
        Mode,
        master::{Config as SpiConfig, Spi},
    },
    time::Rate,
};
use kerfmeter_protocol::DeviceConfig;

use super::pins::EncoderPins;
use crate::as5048a::{As5048a, EncoderSettings};

/// AS5048A SPI clock: the part allows 10 MHz.
pub const ENCODER_SPI_FREQUENCY: Rate = Rate::from_mhz(10);

/// The AS5048A on SPI2, with its chip select, as a blocking embedded-hal `SpiDevice`.
pub type EncoderSpi = ExclusiveDevice<Spi<'static, Blocking>, Output<'static>, Delay>;
/// The encoder driver on the board.
pub type BoardEncoder = As5048a<EncoderSpi>;

/// The encoder driver on SPI2 and `pins`, with the zero, placement and sense of `config`.
///
/// Panics if SPI2 refuses its configuration (10 MHz is well within its range).
pub fn encoder(spi2: SPI2<'static>, pins: EncoderPins, config: &DeviceConfig) -> BoardEncoder {
    let spi = Spi::new(
        spi2,
        SpiConfig::default()
            .with_frequency(ENCODER_SPI_FREQUENCY)
            .with_mode(Mode::_1),
    )
    .expect("SPI2 config")
    .with_sck(pins.sclk)
    .with_mosi(pins.mosi)
    .with_miso(pins.miso);
    let cs = Output::new(pins.cs, Level::High, OutputConfig::default());
    let Ok(spi) = ExclusiveDevice::new(spi, cs, Delay::new());
    As5048a::new(spi, EncoderSettings::from_config(config))
}

//! The AS5048A on the chip: SPI2 in mode 1 at 2 MHz ([`as5048a::SPI_FREQUENCY_HZ`], see its docs),
//! blocking (a frame of two bytes takes 8 µs plus the chip-select times, less than handing it to
//! DMA would cost), with the chip select as a plain GPIO that idles high; then the library's
//! [`As5048a`] driver over it.
//!
//! Chip-select timing: the driver puts the setup (t_L) and hold (t_H) times into each frame's
//! transaction as `DelayNs` operations, which [`ExclusiveDevice`] runs with CSn low; [`EncoderSpi`]
//! then keeps CSn high for t_CSn before the next frame can start. The delays come from
//! [`CsDelay`], which never waits less than asked (esp-hal's `Delay` counts whole microseconds
//! on a microsecond clock, so asked for 1 µs it may return at once after a clock tick).

use embedded_hal::delay::DelayNs;
use embedded_hal::spi::{ErrorType, Operation, SpiDevice};
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
use crate::as5048a::{self, As5048a, CS_HIGH_NS, EncoderSettings};

/// AS5048A SPI clock: [`as5048a::SPI_FREQUENCY_HZ`] (the part allows 10 MHz).
pub const ENCODER_SPI_FREQUENCY: Rate = Rate::from_hz(as5048a::SPI_FREQUENCY_HZ);

/// A busy-wait of at least the time asked for: esp-hal's [`Delay`] rounded up by one whole
/// microsecond, since its clock counts whole microseconds and a wait of n of them can end just
/// after n − 1 have passed.
#[derive(Clone, Copy, Default)]
pub struct CsDelay;

impl DelayNs for CsDelay {
    fn delay_ns(&mut self, ns: u32) {
        Delay::new().delay_micros(ns.div_ceil(1000).saturating_add(1));
    }
}

/// The AS5048A on SPI2 with its chip select, as a blocking embedded-hal `SpiDevice`: CSn low for
/// each transaction (with the transaction's own delays), then high for at least t_CSn
/// ([`CS_HIGH_NS`]) before the next one.
pub struct EncoderSpi {
    device: ExclusiveDevice<Spi<'static, Blocking>, Output<'static>, CsDelay>,
}

impl ErrorType for EncoderSpi {
    type Error =
        <ExclusiveDevice<Spi<'static, Blocking>, Output<'static>, CsDelay> as ErrorType>::Error;
}

impl SpiDevice<u8> for EncoderSpi {
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), Self::Error> {
        let result = self.device.transaction(operations);
        CsDelay.delay_ns(CS_HIGH_NS);
        result
    }
}

/// The encoder driver on the board.
pub type BoardEncoder = As5048a<EncoderSpi>;

/// The encoder driver on SPI2 and `pins`, with the zero, placement and sense of `config`.
///
/// Panics if SPI2 refuses its configuration (2 MHz is well within its range).
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
    let Ok(device) = ExclusiveDevice::new(spi, cs, CsDelay);
    As5048a::new(EncoderSpi { device }, EncoderSettings::from_config(config))
}

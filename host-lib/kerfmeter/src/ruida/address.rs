//! Where a Ruida controller is ([`RuidaAddress`]): `ruida:HOST[:PORT]` with what cannot be read
//! from the controller as query parameters: `z-mm=MIN,MAX` (the travel of the prongs' axis, which
//! no register is known to report; required), `bed-mm=W,H` (when the bed-size registers read
//! nothing), `axis=z|u` (which axis lowers the prongs; Z by default), `local-port=N` (where the
//! controller's answers come: 40200 by default, as MeerK40t listens for them).

use std::str::FromStr;

use super::RuidaFailure;
use crate::grbl::CutterError;

/// Which axis lowers the prongs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ProngAxis {
    /// The Z axis (`D9 02`, register 04 41).
    #[default]
    Z,
    /// The U axis (`D9 03`, register 04 51).
    U,
}

/// A Ruida controller's address and the travel the address gives.
#[derive(Debug, Clone, PartialEq)]
pub struct RuidaAddress {
    /// Host name or IP address.
    pub host: String,
    /// UDP port ([`kerfmeter_ruida::UDP_PORT`] unless given).
    pub port: u16,
    /// The prongs' axis's travel, mm (lowest, highest), machine coordinates.
    pub z_travel_mm: [f64; 2],
    /// The bed, mm, when given (else read from the controller; checked against it when both).
    pub bed_mm: Option<[f64; 2]>,
    /// The bed a front end gives (`job --bed-mm`), taken only when the controller's registers
    /// read none and the address gives none (not checked against the registers: a job may place
    /// its gauge on less than the whole bed).
    pub fallback_bed_mm: Option<[f64; 2]>,
    /// Which axis lowers the prongs.
    pub prong_axis: ProngAxis,
    /// The local UDP port answers come to ([`kerfmeter_ruida::REPLY_UDP_PORT`] unless
    /// `local-port=N` says; 0 for an ephemeral one).
    pub local_port: u16,
}

impl FromStr for RuidaAddress {
    type Err = CutterError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let bad = |reason: &str| -> CutterError {
            RuidaFailure::Address {
                text: text.to_owned(),
                reason: reason.to_owned(),
            }
            .into()
        };
        let rest = text
            .strip_prefix("ruida:")
            .ok_or_else(|| bad("no ruida:"))?;
        let (host_port, query) = rest.split_once('?').unwrap_or((rest, ""));
        let (host, port) = match host_port.rsplit_once(':') {
            Some((h, p)) => (h, p.parse().map_err(|_| bad("the port is not a number"))?),
            None => (host_port, kerfmeter_ruida::UDP_PORT),
        };
        if host.is_empty() {
            return Err(bad("no host"));
        }
        let mut address = Self {
            host: host.to_owned(),
            port,
            z_travel_mm: [f64::NAN; 2],
            bed_mm: None,
            fallback_bed_mm: None,
            prong_axis: ProngAxis::Z,
            local_port: kerfmeter_ruida::REPLY_UDP_PORT,
        };
        for pair in query.split('&').filter(|p| !p.is_empty()) {
            address.set(pair).map_err(|r| bad(&r))?;
        }
        if address.z_travel_mm.iter().any(|z| z.is_nan()) {
            return Err(bad(
                "z-mm=MIN,MAX is required: no register is known to report the travel of the axis that lowers the prongs, and nothing is sent outside the machine's travel",
            ));
        }
        Ok(address)
    }
}

impl RuidaAddress {
    /// Apply one `key=value`.
    fn set(&mut self, pair: &str) -> Result<(), String> {
        let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
        match key {
            "z-mm" => {
                let [lo, hi] = two(value)?;
                if lo >= hi {
                    return Err(format!("z-mm={value}: MIN must be below MAX"));
                }
                self.z_travel_mm = [lo, hi];
            }
            "bed-mm" => {
                let bed = two(value)?;
                if bed.iter().any(|v| *v <= 0.0) {
                    return Err(format!("bed-mm={value}: both above 0"));
                }
                self.bed_mm = Some(bed);
            }
            "axis" => {
                self.prong_axis = match value {
                    "z" | "Z" => ProngAxis::Z,
                    "u" | "U" => ProngAxis::U,
                    _ => return Err(format!("axis={value}: z or u")),
                }
            }
            "local-port" => {
                self.local_port = value
                    .parse()
                    .map_err(|_| format!("local-port={value}: a port, 0 to 65535"))?;
            }
            _ => return Err(format!("unknown parameter `{key}`")),
        }
        Ok(())
    }
}

/// `A,B` as two finite numbers.
fn two(value: &str) -> Result<[f64; 2], String> {
    let parts: Vec<f64> = value
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("`{value}` is not two numbers A,B"))?;
    match parts[..] {
        [a, b] if a.is_finite() && b.is_finite() => Ok([a, b]),
        _ => Err(format!("`{value}` is not two numbers A,B")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_address_needs_the_z_travel_and_reads_its_parameters() {
        let a: RuidaAddress = "ruida:192.168.1.100?z-mm=-20,30&axis=u".parse().unwrap();
        assert_eq!(a.host, "192.168.1.100");
        assert_eq!(a.port, 50200);
        assert_eq!(a.z_travel_mm, [-20.0, 30.0]);
        assert_eq!(a.prong_axis, ProngAxis::U);
        let a: RuidaAddress = "ruida:laser:50300?z-mm=0,10&bed-mm=900,600"
            .parse()
            .unwrap();
        assert_eq!((a.port, a.bed_mm), (50300, Some([900.0, 600.0])));
        for bad in [
            "ruida:host",
            "ruida:?z-mm=0,1",
            "ruida:h?z-mm=1,0",
            "ruida:h?z-mm=0,1&x=2",
        ] {
            let e = bad.parse::<RuidaAddress>().unwrap_err().to_string();
            assert!(e.contains("cannot understand the Ruida address"), "{e}");
        }
    }
}

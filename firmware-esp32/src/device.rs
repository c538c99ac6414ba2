//! The device behind the link: answers each request from the device's state.
//!
//! For now the device answers `GetInfo` and refuses every other request with the typed
//! [`ErrorCode::Unsupported`]; the measuring controller plugs in here.

use kerfmeter_protocol::{DeviceInfo, ErrorCode, Request, Response};

use crate::link::Handler;

/// The device's request handler.
pub struct Device {
    info: DeviceInfo,
}

impl Device {
    /// A device that reports itself as `board` with this boot's random `boot_id`.
    pub fn new(board: &str, boot_id: u32) -> Self {
        Self {
            info: crate::build::device_info(board, boot_id),
        }
    }

    /// What `GetInfo` answers.
    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }
}

impl Handler for Device {
    fn handle(&mut self, request: &Request) -> Response {
        match request {
            Request::GetInfo => Response::Info(self.info.clone()),
            _ => Response::Error(ErrorCode::Unsupported),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_info_and_refuses_the_rest_with_a_typed_error() {
        let mut d = Device::new("twin", 0x1234);
        match d.handle(&Request::GetInfo) {
            Response::Info(i) => {
                assert_eq!(i.boot_id, 0x1234);
                assert_eq!(i.hardware.board.as_str(), "twin");
                assert_eq!(i.protocol, kerfmeter_protocol::PROTOCOL_VERSION);
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(
            d.handle(&Request::GetKerf),
            Response::Error(ErrorCode::Unsupported)
        );
    }
}

//! What the twin's integration tests share: a measurement as a host makes one.

use kerfmeter_protocol::{Fault, KerfResult, Request, Response, RunParams, RunState};
use kerfmeter_twin::Twin;

/// Run one measurement with `params`, polling like a host every 10 ms; the run's end or its
/// fault.
pub fn measure(twin: &mut Twin, params: &RunParams) -> Result<KerfResult, Fault> {
    assert_eq!(twin.request(&Request::Run(*params)), Response::Ok);
    for _ in 0..3000 {
        twin.advance_ticks(10);
        let Response::Status(s) = twin.request(&Request::GetStatus) else {
            panic!("no status");
        };
        match s.state {
            RunState::Done => match twin.request(&Request::GetKerf) {
                Response::Kerf(Some(k)) => return Ok(k),
                other => panic!("no result after Done: {other:?}"),
            },
            RunState::Fault(f) => return Err(f),
            _ => {}
        }
    }
    panic!("the run neither finished nor faulted in 30 s");
}

#![cfg(test)]
//! A method that exists only in the library's tests: traditional frameless rendering
//! with its own budget of 100K samples/s whatever the rate, registered with one line in
//! `methods/mod.rs` to show that this file and that line are all a new method needs
//! (`evaluation`'s tests run it by name).

use super::{frameless::Traditional, Budget, MethodInfo, MethodContext};

/// `test-frameless`.
pub const TEST_FRAMELESS: MethodInfo = MethodInfo {
    name: "test-frameless",
    description: "traditional frameless at its own 100K samples/s (a test of the registry)",
    budget: Budget::Own(|_| 100_000.0),
    check_rate: super::any_rate,
    build: |ctx| {
        let own = MethodContext {
            clock: crate::clock::Clock {
                rate: 100_000.0,
                ..ctx.clock
            },
            ..ctx.clone()
        };
        Ok(Box::new(Traditional::new(&own)))
    },
};


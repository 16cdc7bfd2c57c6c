//! MERL `.binary` bytes through `renderer::formats::merl::MerlTable::from_bytes`: the input as it is
//! (header and size checks, which must reject wrong sizes before allocating), then, when it
//! starts with the valid header and a whole number of values, the full-size file it stands
//! for (`renderer_fuzz::merl_full_size`) so the value checks run too.
#![no_main]

use libfuzzer_sys::fuzz_target;
use renderer::formats::merl::{lookup_trilinear_measured, MerlTable};
use renderer_fuzz::{check_file_error, merl_full_size};

fuzz_target!(|data: &[u8]| {
    let check = |bytes: &[u8]| match MerlTable::from_bytes(bytes, "fuzz.binary") {
        Ok(table) => {
            let v = lookup_trilinear_measured(&table.measured_values(), 0.3, 0.2, 1.0);
            assert!(v.is_none_or(|v| v.iter().all(|c| c.is_finite())));
            assert!(table.raw().iter().all(|v| v.is_finite()));
        }
        Err(error) => check_file_error(&error),
    };
    check(data);
    if let Some(full) = merl_full_size(data) {
        check(&full);
    }
});

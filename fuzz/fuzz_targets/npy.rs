//! One NBRDF `.npy` tensor: the first byte (mod 6) picks which (fc1, b1, fc2, b2, fc3, b3),
//! the rest is the file. It goes through `renderer::neural::nbrdf::tensor_from_bytes` and, in place
//! of that tensor among five valid ones, `NbrdfNetwork::from_npy_bytes`; a network that
//! loads must evaluate to finite, non-negative values.
#![no_main]

use libfuzzer_sys::fuzz_target;
use renderer::neural::nbrdf::{tensor_from_bytes, NbrdfNetwork, TENSOR_NAMES};
use renderer_fuzz::{check_file_error, fuzz_path, split_npy_input, valid_npy_tensors};

fuzz_target!(|data: &[u8]| {
    let Some((which, bytes)) = split_npy_input(data) else {
        return;
    };
    let name = TENSOR_NAMES[which];
    let path = fuzz_path(&format!("net_{name}.npy"));
    if let Err(error) = tensor_from_bytes(bytes, name, &path) {
        check_file_error(&error);
    }
    let valid = valid_npy_tensors();
    let files: [&[u8]; 6] = std::array::from_fn(|i| if i == which { bytes } else { &valid[i][..] });
    match NbrdfNetwork::from_npy_bytes(files, &fuzz_path("net")) {
        Ok(net) => {
            let f = net.eval_angles(0.3, 0.2, 1.0);
            assert!(f.is_finite() && f.min_element() >= 0.0, "{f}");
        }
        Err(error) => {
            check_file_error(&error);
            let message = error.to_string();
            assert!(message.contains(&format!("net_{name}.npy")), "{message}");
        }
    }
});

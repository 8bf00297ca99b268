//! ONNX float16 and bfloat16 initializers as ONNX keeps them when they are not raw: each
//! value's 16 bits in `int32_data`, packed or one field each (the ONNX IR's TensorProto).
//! The values are bit patterns whose floats are known by hand.

mod support;

use firmware::network::shapes;
use support::build::*;
use weights::checkpoint::import;

/// float16 bit patterns and their values: 1.5, 2.25, -1, the smallest subnormal, the largest
/// finite.
const F16: [(u16, f32); 5] = [
    (0x3e00, 1.5),
    (0x4080, 2.25),
    (0xbc00, -1.0),
    (0x0001, 1.0 / 16_777_216.0),
    (0x7bff, 65504.0),
];

/// How an initializer's 16-bit values are written.
#[derive(Clone, Copy)]
enum Store {
    Raw,
    Packed,
    Unpacked,
}

/// The width-16 network with element `i` of every tensor `bits(i)`, of ONNX data type
/// `dtype` (10 float16, 16 bfloat16), stored as `store` says.
fn model(dtype: u64, bits: impl Fn(usize) -> u64, store: Store) -> Vec<u8> {
    let sizes: Vec<Vec<usize>> = shapes(16, 2).iter().map(|s| s.dims().to_vec()).collect();
    let init = |name: &str, t: usize| {
        let dims = &sizes[t];
        let values: Vec<u64> = (0..dims.iter().product()).map(&bits).collect();
        let mut m = Vec::new();
        for &d in dims {
            int_field(1, d as u64, &mut m);
        }
        int_field(2, dtype, &mut m);
        match store {
            Store::Raw => {
                let raw: Vec<u8> = values
                    .iter()
                    .flat_map(|&v| (v as u16).to_le_bytes())
                    .collect();
                bytes_field(9, &raw, &mut m);
            }
            Store::Packed => {
                let mut run = Vec::new();
                values.iter().for_each(|&v| varint(v, &mut run));
                bytes_field(5, &run, &mut m);
            }
            Store::Unpacked => values.iter().for_each(|&v| int_field(5, v, &mut m)),
        }
        bytes_field(8, name.as_bytes(), &mut m);
        m
    };
    onnx_model(onnx_fields_by(init))
}

#[test]
fn float16_in_int32_data_imports_the_values_its_bits_stand_for() {
    let bits = |i: usize| u64::from(F16[i % F16.len()].0);
    for store in [Store::Raw, Store::Packed, Store::Unpacked] {
        let got = import(&model(10, bits, store), None).unwrap();
        assert_eq!(got.converted_from.as_deref(), Some("F16"));
        for t in got.weights.tensors() {
            let want: Vec<f32> = (0..t.len()).map(|i| F16[i % F16.len()].1).collect();
            assert_eq!(t, &want);
        }
    }
}

#[test]
fn bfloat16_in_int32_data_imports_the_top_half_of_an_f32() {
    // bfloat16 is an f32's upper 16 bits: 0x3fc0 is 1.5, 0xc010 is -2.25.
    let bits = |i: usize| if i.is_multiple_of(2) { 0x3fc0 } else { 0xc010 };
    for store in [Store::Packed, Store::Unpacked] {
        let got = import(&model(16, bits, store), None).unwrap();
        assert_eq!(got.converted_from.as_deref(), Some("BF16"));
        for t in got.weights.tensors() {
            let want: Vec<f32> = (0..t.len()).map(|i| [1.5, -2.25][i % 2]).collect();
            assert_eq!(t, &want);
        }
    }
}

#[test]
fn a_value_wider_than_16_bits_in_int32_data_is_refused_by_name() {
    let bits = |i: usize| if i == 3 { 70_000 } else { 0x3c00 };
    let e = import(&model(10, bits, Store::Packed), None).unwrap_err();
    assert!(e.is_input(), "{e}");
    assert!(
        e.to_string()
            .contains("initializer \"w0\": int32_data holds 70000 for a 16-bit float"),
        "{e}"
    );
}

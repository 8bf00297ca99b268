use super::*;
use std::cmp::Ordering;

use super::choose::natural;
use firmware::network::shapes;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};
use state_dict::f16_to_f32;

/// A width-16 network's tensors with recognisable values: tensor `t`, element `i` is
/// `t + i / 1000`.
fn values() -> [Vec<f32>; 6] {
    let mut t = 0;
    shapes(16, 2).map(|s| {
        t += 1;
        (0..s.len()).map(|i| t as f32 + i as f32 / 1000.0).collect()
    })
}

/// Safetensors bytes holding the width-16 network under `names` (six names, canonical
/// order), plus `extra` tensors of shape [3].
fn file(names: [&str; 6], extra: &[&str]) -> Vec<u8> {
    let v = values();
    let bytes: Vec<Vec<u8>> = v
        .iter()
        .map(|t| t.iter().flat_map(|x| x.to_le_bytes()).collect())
        .collect();
    let three = [0u8; 12];
    let mut views: Vec<(String, TensorView)> = names
        .iter()
        .zip(shapes(16, 2))
        .zip(&bytes)
        .map(|((n, s), b)| {
            (
                n.to_string(),
                TensorView::new(Dtype::F32, s.dims().to_vec(), b).unwrap(),
            )
        })
        .collect();
    for e in extra {
        views.push((
            e.to_string(),
            TensorView::new(Dtype::F32, vec![3], &three).unwrap(),
        ));
    }
    safetensors::serialize(views, None).unwrap()
}

fn with_prefix(p: &str, layers: [&str; 3]) -> [String; 6] {
    let mut out: [String; 6] = Default::default();
    for (k, l) in layers.iter().enumerate() {
        out[2 * k] = format!("{p}{l}.weight");
        out[2 * k + 1] = format!("{p}{l}.bias");
    }
    out
}

fn named(p: &str, layers: [&str; 3], extra: &[&str]) -> Vec<u8> {
    let n = with_prefix(p, layers);
    file(n.each_ref().map(String::as_str), extra)
}

fn err(bytes: &[u8], prefix: Option<&str>) -> String {
    import(bytes, prefix).unwrap_err().to_string()
}

#[test]
fn every_usual_layout_imports_to_the_same_weights() {
    for (p, layers) in [
        ("", ["fc1", "fc2", "fc3"]),
        ("", ["0", "2", "4"]),
        ("network.", ["0", "2", "4"]),
        ("q_net.q_net.", ["0", "2", "4"]),
        ("model.", ["layer2", "layer9", "layer10"]),
        ("", ["input", "hidden", "output"]),
    ] {
        let got = import(&named(p, layers, &[]), None).unwrap();
        assert_eq!(got.weights.tensors(), &values(), "{p}{layers:?}");
        assert_eq!(got.prefix, p);
        assert_eq!(got.layers, layers.map(String::from), "{p}");
        assert_eq!((got.ignored, got.converted_from.as_deref()), (0, None));
    }
}

#[test]
fn natural_order_puts_fc2_before_fc10() {
    // In plain string order fc10 < fc2, which would put the output layer in the middle.
    let got = import(&named("", ["fc1", "fc2", "fc10"], &[]), None).unwrap();
    assert_eq!(got.layers, ["fc1", "fc2", "fc10"].map(String::from));
    assert_eq!(natural("fc2", "fc10"), Ordering::Less);
    assert_eq!(natural("2", "10"), Ordering::Less);
    assert_eq!(natural("layer", "layer1"), Ordering::Less);
}

#[test]
fn two_networks_are_refused_with_both_prefixes_unless_one_is_chosen() {
    let mut a = with_prefix("q_net.q_net.", ["0", "2", "4"]).to_vec();
    a.extend(with_prefix("q_net_target.q_net.", ["0", "2", "4"]));
    // Two networks in one file: serialise twelve tensors.
    let v = values();
    let bytes: Vec<Vec<u8>> = v
        .iter()
        .chain(&v)
        .map(|t| t.iter().flat_map(|x| x.to_le_bytes()).collect())
        .collect();
    let views: Vec<_> = a
        .iter()
        .zip(shapes(16, 2).iter().chain(&shapes(16, 2)))
        .zip(&bytes)
        .map(|((n, s), b)| {
            (
                n.clone(),
                TensorView::new(Dtype::F32, s.dims().to_vec(), b).unwrap(),
            )
        })
        .collect();
    let two = safetensors::serialize(views, None).unwrap();
    let e = err(&two, None);
    assert!(
        e.contains("2 networks found, under the prefixes q_net.q_net., q_net_target.q_net.")
            && e.contains("--prefix"),
        "{e}"
    );
    for p in ["q_net.q_net.", "q_net_target.q_net."] {
        let got = import(&two, Some(p)).unwrap();
        assert_eq!((got.prefix.as_str(), got.ignored), (p, 6));
        assert_eq!(got.weights.tensors(), &values());
    }
    let e = err(&two, Some("q_net."));
    assert!(e.contains("no tensors under prefix \"q_net.\""), "{e}");
}

#[test]
fn tensors_outside_the_network_need_an_explicit_prefix() {
    let bytes = named("network.", ["0", "2", "4"], &["log_std"]);
    let e = err(&bytes, None);
    assert!(
        e.contains("1 tensors are not part of the network under prefix \"network.\"")
            && e.contains("\"log_std\"")
            && e.contains("--prefix network."),
        "{e}"
    );
    let got = import(&bytes, Some("network.")).unwrap();
    assert_eq!(got.ignored, 1);
    assert!(got.describe().contains("1 other tensors ignored"));
}

/// The file's layer names reach the log line quoted: a name with a line break or an escape
/// sequence neither starts a line nor reaches the terminal raw.
#[test]
fn the_description_quotes_the_files_layer_names() {
    let layers = ["q\nerror: fake fc1", "\u{1b}[31mfc2", "fc3"];
    let got = import(&named("", layers, &[]), None).unwrap();
    let d = got.describe();
    assert!(
        d.starts_with(r#"layers "q\nerror: fake fc1", "\u{1b}[31mfc2", "fc3" under no prefix"#),
        "{d}"
    );
    assert!(!d.chars().any(char::is_control), "{d}");
}

#[test]
fn shapes_that_do_not_make_the_network_say_why() {
    // A fourth layer.
    let mut n = with_prefix("", ["0", "2", "4"]).to_vec();
    n.push("6.weight".into());
    let v = values();
    let mut tensors: Vec<(String, Vec<usize>, Vec<u8>)> = n[..6]
        .iter()
        .zip(shapes(16, 2))
        .zip(&v)
        .map(|((n, s), t)| {
            (
                n.clone(),
                s.dims().to_vec(),
                t.iter().flat_map(|x| x.to_le_bytes()).collect(),
            )
        })
        .collect();
    tensors.push(("6.weight".into(), vec![2, 2], vec![0; 16]));
    let ser = |t: &[(String, Vec<usize>, Vec<u8>)]| {
        let views: Vec<_> = t
            .iter()
            .map(|(n, s, b)| {
                (
                    n.clone(),
                    TensorView::new(Dtype::F32, s.clone(), b).unwrap(),
                )
            })
            .collect();
        safetensors::serialize(views, None).unwrap()
    };
    let e = err(&ser(&tensors), None);
    assert!(
        e.contains("4 layers (\"0\", \"2\", \"4\", \"6\"), expected 3 linear layers"),
        "{e}"
    );
    // Five inputs.
    tensors.pop();
    tensors[0] = ("0.weight".into(), vec![16, 5], vec![0; 16 * 5 * 4]);
    let e = err(&ser(&tensors), None);
    assert!(
        e.contains("the first layer takes the 4 observations"),
        "{e}"
    );
    // Unequal hidden widths: 16 then 8.
    tensors[0] = ("0.weight".into(), vec![16, 4], vec![0; 16 * 4 * 4]);
    tensors[2] = ("2.weight".into(), vec![8, 16], vec![0; 8 * 16 * 4]);
    tensors[3] = ("2.bias".into(), vec![8], vec![0; 8 * 4]);
    tensors[4] = ("4.weight".into(), vec![2, 8], vec![0; 2 * 8 * 4]);
    let e = err(&ser(&tensors), None);
    assert!(e.contains("hidden widths 16 and 8 differ"), "{e}");
    // A bias of the wrong length.
    let mut t = tensors.clone();
    t[3] = ("2.bias".into(), vec![9], vec![0; 9 * 4]);
    let e = err(&ser(&t), None);
    assert!(e.contains("\"2.bias\" has shape [9], expected [8]"), "{e}");
    // A missing bias.
    t.remove(3);
    let e = err(&ser(&t), None);
    assert!(e.contains("layer \"2\" lacks its bias"), "{e}");
}

#[test]
fn unsupported_widths_and_bad_values_are_named_in_the_files_own_terms() {
    let mut bytes = named("network.", ["0", "2", "4"], &[]);
    // The first NaN of `network.4.weight` (tensor 5 of 6, element 3) in place of a value.
    let st = SafeTensors::deserialize(&bytes).unwrap();
    let off =
        st.tensor("network.4.weight").unwrap().data().as_ptr() as usize - bytes.as_ptr() as usize;
    bytes[off + 12..off + 16].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = err(&bytes, None);
    assert!(e.contains("\"network.4.weight\": element 3 is NaN"), "{e}");
}

#[test]
fn other_float_types_are_converted_and_said() {
    let v = values();
    let names = with_prefix("", ["fc1", "fc2", "fc3"]);
    for (dtype, width) in [(Dtype::F64, 8), (Dtype::F16, 2), (Dtype::BF16, 2)] {
        let bytes: Vec<Vec<u8>> = v
            .iter()
            .map(|t| {
                t.iter()
                    .flat_map(|&x| match dtype {
                        Dtype::F64 => f64::from(x).to_le_bytes().to_vec(),
                        // 1.5 and 2.25 are exact in every format.
                        _ => {
                            let y: f32 = if x.fract() < 0.5 { 1.5 } else { 2.25 };
                            if dtype == Dtype::BF16 {
                                ((y.to_bits() >> 16) as u16).to_le_bytes().to_vec()
                            } else {
                                // f16 of 1.5 is 0x3e00, of 2.25 is 0x4080.
                                (if y == 1.5 { 0x3e00u16 } else { 0x4080 })
                                    .to_le_bytes()
                                    .to_vec()
                            }
                        }
                    })
                    .collect()
            })
            .collect();
        let file = |bytes: &[Vec<u8>]| {
            let views = names
                .iter()
                .zip(shapes(16, 2))
                .zip(bytes)
                .map(|((n, s), b)| {
                    (
                        n.clone(),
                        TensorView::new(dtype, s.dims().to_vec(), b).unwrap(),
                    )
                });
            safetensors::serialize(views, None).unwrap()
        };
        assert_eq!(bytes[0].len(), 64 * width);
        let got = import(&file(&bytes), None).unwrap();
        assert_eq!(got.converted_from, Some(format!("{dtype:?}")));
        if dtype == Dtype::F64 {
            assert_eq!(got.weights.tensors(), &v);
            // Finite as given, past f32's range: named so, not as the infinity it rounds to.
            let mut bytes = bytes.clone();
            bytes[2][8..16].copy_from_slice(&3.5e38f64.to_le_bytes());
            let e = err(&file(&bytes), None);
            assert!(
                e.contains("\"fc2.weight\": element 1 is 3.5e38, past float32's range"),
                "{e}"
            );
        } else {
            assert!(
                got.weights
                    .tensors()
                    .iter()
                    .flatten()
                    .all(|&x| x == 1.5 || x == 2.25)
            );
        }
    }
}

#[test]
fn f16_widening_is_exact_for_every_class_of_value() {
    assert_eq!(f16_to_f32(0x0000).to_bits(), 0.0f32.to_bits());
    assert_eq!(f16_to_f32(0x8000).to_bits(), (-0.0f32).to_bits());
    assert_eq!(f16_to_f32(0x3c00), 1.0);
    assert_eq!(f16_to_f32(0xc000), -2.0);
    assert_eq!(f16_to_f32(0x7bff), 65504.0);
    assert_eq!(f16_to_f32(0x0001), 2f32.powi(-24));
    assert_eq!(f16_to_f32(0x03ff), 1023.0 * 2f32.powi(-24));
    assert_eq!(f16_to_f32(0x0200), 2f32.powi(-15));
    assert_eq!(f16_to_f32(0x7c00), f32::INFINITY);
    assert!(f16_to_f32(0x7e00).is_nan());
}

#[test]
fn headers_and_garbage_are_refused_before_parsing() {
    let e = err(b"short", None);
    assert!(e.contains("shorter than its 8-byte header length"), "{e}");
    let mut huge = (u64::MAX).to_le_bytes().to_vec();
    huge.extend_from_slice(b"{}");
    let e = err(&huge, None);
    assert!(e.contains("expected at most 1048576"), "{e}");
    let mut junk = 4u64.to_le_bytes().to_vec();
    junk.extend_from_slice(b"nope");
    assert!(err(&junk, None).contains("not a safetensors file"));
    let mut long = 100u64.to_le_bytes().to_vec();
    long.extend_from_slice(b"{}");
    let e = err(&long, None);
    assert!(
        e.contains("declares 100 bytes, more than the 2 after its length"),
        "{e}"
    );
    // A length that runs past the JSON into the tensors' bytes.
    let w = Weights::new(16, crate::BANG_BANG.to_vec(), values()).unwrap();
    let mut file = to_safetensors(&w, &BTreeMap::new()).unwrap();
    let len = u64::from_le_bytes(*file.first_chunk::<8>().unwrap());
    file[..8].copy_from_slice(&(len + 100).to_le_bytes());
    let e = err(&file, None);
    assert!(
        e.contains("not UTF-8 text: expected the header's JSON alone"),
        "{e}"
    );
}

#[test]
fn a_header_key_given_twice_is_refused_not_the_last_taken() {
    let bytes = named("", ["fc1", "fc2", "fc3"], &[]);
    let n = u64::from_le_bytes(bytes[..8].try_into().unwrap()) as usize;
    let header = std::str::from_utf8(&bytes[8..8 + n]).unwrap();
    let with = |header: String| {
        let mut out = (header.len() as u64).to_le_bytes().to_vec();
        out.extend(header.as_bytes());
        out.extend(&bytes[8 + n..]);
        out
    };
    let at = header.find("\"fc1.bias\"").unwrap();
    let end = at + header[at..].find('}').unwrap() + 1;
    let tensor_twice = format!("{{{},{}", &header[at..end], &header[1..]);
    let meta_twice = format!(
        "{{\"__metadata__\":{{\"rig\":\"a\",\"rig\":\"b\"}},{}",
        &header[1..]
    );
    for (edited, key) in [(tensor_twice, "fc1.bias"), (meta_twice, "rig")] {
        let e = err(&with(edited), None);
        assert!(e.contains(&format!("found \"{key}\" twice")), "{e}");
    }
    assert!(import(&with(header.to_string()), None).is_ok());
}

#[test]
fn a_recorded_width_is_the_tensors_or_the_file_is_refused() {
    let w = Weights::new(16, crate::BANG_BANG.to_vec(), values()).unwrap();
    let with = |width: &str| {
        let meta = BTreeMap::from([(WIDTH_KEY.to_string(), width.to_string())]);
        import(&to_safetensors(&w, &meta).unwrap(), None)
    };
    assert_eq!(with("16").unwrap().weights, w);
    for (width, says) in [
        (
            "128",
            "metadata `width` is \"128\", expected 16, the width of its tensors",
        ),
        ("16.0", "is \"16.0\""),
        ("", "is \"\""),
        ("+16", "is \"+16\""),
        ("016", "is \"016\""),
        ("16 ", "is \"16 \""),
    ] {
        let e = with(width).unwrap_err();
        assert!(e.is_input() && e.to_string().contains(says), "{width}: {e}");
    }
}

#[test]
fn the_canonical_file_round_trips_and_is_byte_deterministic() {
    let w = Weights::new(16, crate::BANG_BANG.to_vec(), values()).unwrap();
    let meta: BTreeMap<String, String> =
        (0..12).map(|i| (format!("k{i}"), format!("{i}"))).collect();
    let first = to_safetensors(&w, &meta).unwrap();
    for _ in 0..5 {
        assert_eq!(to_safetensors(&w, &meta).unwrap(), first);
    }
    assert_eq!(u64::from_le_bytes(first[..8].try_into().unwrap()) % 8, 0);
    let back = import(&first, None).unwrap();
    assert_eq!(back.weights, w);
    assert_eq!(back.metadata, meta);
    assert_eq!(back.layers, ["fc1", "fc2", "fc3"].map(String::from));
}

#[test]
fn a_long_tensor_name_is_refused_and_quoted_short() {
    let long = format!("{}.weight", "x".repeat(100_000));
    let bytes = file(
        [
            "fc1.weight",
            "fc1.bias",
            "fc2.weight",
            "fc2.bias",
            "fc3.weight",
            "fc3.bias",
        ],
        &[&long],
    );
    let e = err(&bytes, None);
    assert!(
        e.contains("tensor names must be at most 200 bytes, found one of 100007") && e.len() < 400,
        "{}",
        e.len()
    );
}

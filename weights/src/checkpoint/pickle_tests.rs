use super::machine::{Machine, Ops, long1};
use super::*;

/// The pickle of `{"w": tensor}` as `torch.save` (protocol 2) writes it, for a float
/// storage `"0"` of `numel` elements viewed at `offset` with `shape` and `stride` (one
/// dimension each); the opcodes of `pickletools.dis` on a real file.
fn one_tensor(global: &[u8], numel: u8, offset: u8, size: u8, stride: u8) -> Vec<u8> {
    let mut p = b"\x80\x02ccollections\nOrderedDict\nq\x00)Rq\x01(X\x01\x00\x00\x00w".to_vec();
    p.extend_from_slice(b"ctorch._utils\n_rebuild_tensor_v2\nq\x02((X\x07\x00\x00\x00storage");
    p.extend_from_slice(global);
    p.extend_from_slice(b"X\x01\x00\x00\x000X\x03\x00\x00\x00cpuK");
    p.extend_from_slice(&[
        numel, b't', b'Q', b'K', offset, b'K', size, 0x85, b'K', stride,
    ]);
    p.extend_from_slice(b"\x85\x89h\x00)Rtq\x03Ru}X\x09\x00\x00\x00_metadata}sb.");
    p
}

const FLOAT: &[u8] = b"ctorch\nFloatStorage\n";

#[test]
fn a_state_dicts_pickle_reads_as_its_tensors() {
    let bytes = one_tensor(FLOAT, 6, 1, 3, 2);
    let got = state_dict(&bytes).unwrap();
    let want = TensorRef {
        key: "0",
        dtype: Ok(Dtype::F32),
        numel: 6,
        offset: 1,
        shape: [3].into(),
        stride: [2].into(),
    };
    assert_eq!(got, [("w", want)]);
    let bytes = one_tensor(b"ctorch\nHalfStorage\n", 3, 0, 3, 1);
    let half = state_dict(&bytes).unwrap();
    assert_eq!(half[0].1.dtype, Ok(Dtype::F16));
    // An integer buffer reads too, by its element type's name and size.
    let bytes = one_tensor(b"ctorch\nLongStorage\n", 3, 0, 3, 1);
    assert_eq!(state_dict(&bytes).unwrap()[0].1.dtype, Err(("I64", 8)));
}

fn refusal(bytes: &[u8]) -> String {
    let e = state_dict(bytes).unwrap_err();
    assert!(e.is_input());
    e.to_string()
}

#[test]
fn other_globals_and_opcodes_are_refused_by_name() {
    let m = refusal(&one_tensor(b"cposix\nsystem\n", 6, 0, 3, 1));
    assert!(m.contains("refused global \"posix.system\""), "{m}");
    let m = refusal(&one_tensor(b"ctorch\nComplexFloatStorage\n", 6, 0, 3, 1));
    assert!(m.contains("\"torch.ComplexFloatStorage\""), "{m}");
    // INST (`i`), which imports and calls in one opcode.
    let m = refusal(b"\x80\x02(ios\nsystem\n.");
    assert!(
        m.contains("opcode 0x69 (\"i\") is not one a state dict uses"),
        "{m}"
    );
    // REDUCE on an OrderedDict with arguments: a call the format never makes.
    let m = refusal(b"\x80\x02ccollections\nOrderedDict\nK\x01\x85R.");
    assert!(m.contains("REDUCE calls a class with 1 arguments"), "{m}");
}

#[test]
fn malformed_pickles_are_refused_not_trusted() {
    let good = one_tensor(FLOAT, 6, 0, 3, 1);
    for cut in 1..good.len() {
        assert!(state_dict(&good[..cut]).is_err(), "cut at {cut}");
    }
    for (bytes, says) in [
        (&b"\x80\x07."[..], "protocol 7"),
        (
            b"\x80\x02h\x05.",
            "memo entry 5 is read before it is written",
        ),
        (b"\x80\x02K\x01K\x02.", "1 values left on the stack"),
        (b"\x80\x02}K\x01s.", "an opcode needs a value"),
        (b"\x80\x02].", "expected a state dict"),
        (b"\x80\x02}K\x01K\x02s.", "names to be strings"),
        (
            b"\x80\x02}X\x01\x00\x00\x00aK\x02s.",
            "found an int under key \"a\"",
        ),
    ] {
        let m = refusal(bytes);
        assert!(m.contains(says), "{bytes:?}: {m}");
    }
}

#[test]
fn long1_integers_are_twos_complement() {
    let read = |b: &[u8]| {
        let mut m = Machine::default();
        let mut ops = Ops { bytes: b, pos: 0 };
        long1(&mut ops, &mut m).unwrap();
        match *m.pop().unwrap() {
            Value::Int(i) => i,
            _ => unreachable!("long1 pushes an int"),
        }
    };
    // pickletools' examples: 255 is `02 ff 00`, -1 is `01 ff`, 32767 * 65536 + ... .
    assert_eq!(read(&[2, 0xff, 0x00]), 255);
    assert_eq!(read(&[1, 0xff]), -1);
    assert_eq!(read(&[0]), 0);
    assert_eq!(read(&[2, 0x00, 0x80]), -32768);
}

/// A tuple nested as deep as the opcode budget allows: refused, and dropped without
/// recursing (a recursive drop of 60,000 levels overflows a test thread's stack).
#[test]
fn deep_nesting_neither_overflows_nor_is_taken() {
    let mut p = b"\x80\x02)".to_vec();
    p.extend(std::iter::repeat_n(0x85, 60_000));
    p.push(b'.');
    assert!(refusal(&p).contains("found a tuple"));
    // And a list that contains itself, through the memo.
    assert!(refusal(b"\x80\x02]q\x00h\x00a.").contains("found a list"));
}

//! The numbers a person means: a check every number that comes in passes.

/// Whether an input number is one a person means: zero, or normal both in f64 and once a
/// board holds it in f32. A subnormal (`5e-324`, or `1e-40`, which f32 keeps as one) is a
/// slip, lost in the arithmetic, wherever a number comes in. Large values are the ranges'
/// to refuse.
pub fn plain(x: f64) -> bool {
    x == 0.0 || (x.is_normal() && (x as f32).abs() >= f32::MIN_POSITIVE)
}

/// Whether `x` is finite but past f32's range: narrowed, it becomes an infinity, and a
/// refusal of that would call a number given finite infinite.
pub fn past_f32(x: f64) -> bool {
    x.is_finite() && (x as f32).is_infinite()
}

/// `text` as a whole number written in decimal digits alone, if it fits a `T`: `str::parse`
/// also takes a leading `+`, which every refusal of a whole number says it is not.
pub fn whole<T: std::str::FromStr>(text: &str) -> Option<T> {
    let digits = !text.is_empty() && text.bytes().all(|b| b.is_ascii_digit());
    digits.then(|| text.parse().ok()).flatten()
}

/// Whether `text` is a number written with a non-zero digit that reads as zero (`1e-400`):
/// below the range of f64, it parses to 0 and passes every check of [`plain`], as the
/// value a person who wrote it did not mean.
pub fn reads_as_zero(text: &str) -> bool {
    let mantissa = text.split(['e', 'E']).next().unwrap_or_default();
    text.parse::<f64>().is_ok_and(|x| x == 0.0)
        && mantissa.bytes().any(|b| (b'1'..=b'9').contains(&b))
}

/// Why `piece`, which [`reads_as_zero`], is refused: wherever it comes in.
pub fn zero_in_disguise(piece: &str) -> String {
    format!(
        "{piece} reads as 0, below the smallest number a board holds; expected 0 written as 0, \
         or a number of at least {:e}",
        f32::MIN_POSITIVE
    )
}

/// The refusal of the first number of a TOML or JSON `text` that [`reads_as_zero`], outside
/// its comments, with its line and column: both parsers read `1e-400` as 0 without a word.
/// Inside a string a number is a piece of a spec (`levels = "-1,1e-400,1"`, `reward =
/// "env+scale=1e-400"`), cut where the command line's pieces are cut.
pub fn hidden_zero(text: &str) -> Option<String> {
    scan(text, true)
}

/// [`hidden_zero`] of the numbers a file holds as numbers alone, for a file whose strings
/// are free text (a run summary's rig file and its comments, a manifest's words), where a
/// `1e-400` read as 0 is no number of the file's.
pub fn hidden_zero_in_numbers(text: &str) -> Option<String> {
    scan(text, false)
}

/// [`hidden_zero`], looking inside strings too if `in_strings`.
fn scan(text: &str, in_strings: bool) -> Option<String> {
    let (mut start, mut quote, mut comment, mut escaped) = (None, None, false, false);
    for (i, c) in text.char_indices().chain([(text.len(), '\n')]) {
        let joins = if quote.is_some() { "-._" } else { "+-._" };
        let read = !comment && !escaped && (in_strings || quote.is_none());
        let in_token = read && (c.is_ascii_alphanumeric() || joins.contains(c));
        if in_token {
            start.get_or_insert(i);
            continue;
        }
        if let Some(s) = start.take() {
            // A range's ends (`1e-400..0.5`) each.
            let mut at = s;
            for end in text[s..i].split("..") {
                if reads_as_zero(&end.replace('_', "")) {
                    let span = at..at + end.len();
                    return Some(crate::located(text, Some(span), &zero_in_disguise(end)));
                }
                at += end.len() + 2;
            }
        }
        match (quote, c) {
            (_, '\n') => (quote, comment) = (None, false),
            (Some('"'), '\\') => escaped = !escaped,
            (Some(q), c) if c == q && !escaped => quote = None,
            (Some(_), _) => escaped = false,
            (None, '"' | '\'') if !comment => quote = Some(c),
            (None, '#') => comment = true,
            _ => {}
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plain_number_is_zero_or_normal_in_f64_and_in_f32() {
        for x in [0.0, -0.0, 1.0, -2.5e-38, 1.2e-38, 1e300, -1e308] {
            assert!(plain(x), "{x:e}");
        }
        // 1e-38 and 1e-40 are normal in f64 and subnormal in f32; 1e-50 is 0 there.
        for x in [
            5e-324,
            2e-308,
            1e-38,
            -1e-40,
            1e-50,
            f64::NAN,
            f64::INFINITY,
        ] {
            assert!(!plain(x), "{x:e}");
        }
    }

    #[test]
    fn free_text_is_no_number() {
        let text = "{\"rig\": \"# a comment: 1e-400\", \"min\": 5}";
        assert!(hidden_zero(text).is_some());
        assert_eq!(hidden_zero_in_numbers(text), None);
        let at = hidden_zero_in_numbers("{\"about\": \"1e-400\",\n\"min\": 1e-400}").unwrap();
        assert!(
            at.starts_with("line 2, column 8: 1e-400 reads as 0"),
            "{at}"
        );
    }

    #[test]
    fn a_number_below_f64_reads_as_zero_and_a_zero_does_not() {
        for text in ["1e-400", "-1e-400", "10e-400", "0.0001e-330", "1E-999"] {
            assert!(reads_as_zero(text), "{text}");
        }
        for text in [
            "0", "-0", "0.0", "0e5", "00", "5e-324", "1e-40", "abc", "", "inf", "1",
        ] {
            assert!(!reads_as_zero(text), "{text}");
        }
    }

    #[test]
    fn a_toml_number_that_reads_as_zero_is_found_where_it_is_and_nowhere_else() {
        let text = "a = 1\nb = [0.5, 1_0e-40_0, 2] # 1e-400 in a comment\n";
        let found = hidden_zero(text).unwrap();
        assert!(
            found.starts_with("line 2, column 11: 1_0e-40_0 reads as 0"),
            "{found}"
        );
        for clean in [
            "x = 0.0\ny = -0e5 # 1e-400\n",
            "s = \"a1e-400\"\nt = 'run-1e-999'\n",
            "u = \"a \\\" x1e-400\" # \" 1e-400\nv = 5e-324\n",
            "[t.k1e-400]\nk = 1979-05-27\n",
            "w = \"env+scale=1e-5\"\n",
        ] {
            assert_eq!(hidden_zero(clean), None, "{clean}");
        }
        assert!(hidden_zero("w = \"x\"\nz = +1e-400").is_some());
        // A spec in a string, cut as the command line cuts its pieces.
        for (spec, column) in [
            ("levels = \"-1,1e-400,1\"", 14),
            ("reward = \"env+fail-penalty=1e-400\"", 28),
            ("s = '1e-999'", 6),
            ("u = \"\\n1e-400\"", 8),
            ("domain = \"glitch=1e-400..0.3\"", 18),
            ("r = [0.5, 2e-999..1]", 11),
        ] {
            let found = hidden_zero(spec).unwrap_or_default();
            assert!(
                found.starts_with(&format!("line 1, column {column}: ")),
                "{spec}: {found}"
            );
        }
    }

    #[test]
    fn a_whole_number_is_digits_alone() {
        assert_eq!(whole::<u32>("0042"), Some(42));
        assert_eq!(whole::<u32>("4294967295"), Some(u32::MAX));
        for refused in [
            "+3",
            "-0",
            "",
            " 1",
            "1_000",
            "1e3",
            "4294967296",
            "\u{661}",
        ] {
            assert_eq!(whole::<u32>(refused), None, "{refused}");
        }
    }
}

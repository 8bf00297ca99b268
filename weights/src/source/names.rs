//! The names an export gives its items: checked so that the generated source compiles, alone
//! and beside the C API and other exports.

use firmware::rig::Rig;

use super::{levels_item, rig_item};
use crate::{BANG_BANG, Error, Result, quote};
use c_library::c_library_use;

mod c_library;
mod gnu_library;
mod posix_library;

/// Longest name: C guarantees 63 significant characters of an identifier, and the include
/// guard puts 18 before it ([`c_guard`]).
pub const MAX_NAME_CHARS: usize = 40;

/// Refuses a name longer than [`MAX_NAME_CHARS`].
fn check_length(name: &str) -> Result<()> {
    if name.chars().count() <= MAX_NAME_CHARS {
        return Ok(());
    }
    Err(Error::Input(format!(
        "--name: expected at most {MAX_NAME_CHARS} characters, found {} ({})",
        name.chars().count(),
        quote(name)
    )))
}

/// Checks a Rust static's name: at most [`MAX_NAME_CHARS`] characters of upper case, digits
/// and underscores, not starting with a digit (what `non_upper_case_globals` accepts), not a
/// keyword, and none of the module's other items ([`rust_module_items`]).
pub fn check_rust_name(name: &str) -> Result<()> {
    check_length(name)?;
    let ok = name.starts_with(|c: char| c.is_ascii_uppercase() || c == '_')
        && name
            .chars()
            .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
        && name != "_"
        && name != "Self";
    if !ok {
        return Err(Error::Input(format!(
            "--name: expected a Rust static's name (upper case, digits, `_`, e.g. POLICY), \
             found {}",
            quote(name)
        )));
    }
    let items = rust_module_items();
    if items.iter().any(|item| item == name) {
        return Err(Error::Input(format!(
            "--name: expected a name the module does not define itself, found {} (the module \
             defines {} beside the static: a second definition does not compile)",
            quote(name),
            items.join(" and ")
        )));
    }
    Ok(())
}

/// The items a Rust module defines beside its static, `LEVELS` and `RIG`: read from what
/// their writers write, so that the names refused cannot fall out of step with the module.
fn rust_module_items() -> Vec<String> {
    let items = levels_item(&BANG_BANG) + &rig_item(&Rig::GYMNASIUM);
    items
        .lines()
        .filter_map(|line| {
            let rest = line
                .strip_prefix("pub const ")
                .or_else(|| line.strip_prefix("pub static "))?;
            rest.split_once(':').map(|(item, _)| item.to_string())
        })
        .collect()
}

/// C's keywords, C23's among them: `typeof` is one in GCC's default dialect too.
const C_KEYWORDS: [&str; 46] = [
    "auto",
    "break",
    "case",
    "char",
    "const",
    "continue",
    "default",
    "do",
    "double",
    "else",
    "enum",
    "extern",
    "float",
    "for",
    "goto",
    "if",
    "inline",
    "int",
    "long",
    "register",
    "restrict",
    "return",
    "short",
    "signed",
    "sizeof",
    "static",
    "struct",
    "switch",
    "typedef",
    "union",
    "unsigned",
    "void",
    "volatile",
    "while",
    "_Bool",
    "_Complex",
    "_Imaginary",
    "_Alignas",
    "_Alignof",
    "_Atomic",
    "_Generic",
    "_Noreturn",
    "_Static_assert",
    "_Thread_local",
    "typeof",
    "typeof_unqual",
];

/// C++'s keywords beyond C's: the headers are included from C++ too (Arduino sketches).
const CXX_KEYWORDS: [&str; 58] = [
    "alignas",
    "alignof",
    "and",
    "and_eq",
    "asm",
    "bitand",
    "bitor",
    "bool",
    "catch",
    "char16_t",
    "char32_t",
    "char8_t",
    "class",
    "compl",
    "concept",
    "consteval",
    "constexpr",
    "constinit",
    "const_cast",
    "co_await",
    "co_return",
    "co_yield",
    "decltype",
    "delete",
    "dynamic_cast",
    "explicit",
    "export",
    "false",
    "friend",
    "mutable",
    "namespace",
    "new",
    "noexcept",
    "not",
    "not_eq",
    "nullptr",
    "operator",
    "or",
    "or_eq",
    "private",
    "protected",
    "public",
    "reinterpret_cast",
    "requires",
    "static_assert",
    "static_cast",
    "template",
    "this",
    "throw",
    "true",
    "try",
    "typeid",
    "typename",
    "using",
    "virtual",
    "xor",
    "xor_eq",
    "thread_local",
];

/// Checks a C identifier for the header's object: at most [`MAX_NAME_CHARS`] letters, digits
/// and underscores, not starting with a digit or `_`, not a C or C++ keyword, not ending in
/// `_t` (POSIX reserves it), not a name the C library takes
/// ([`c_library_use`]), not ending in `_rig`, `_levels` or `_duty` (so that no header's
/// `NAME_rig`, `NAME_levels` or `NAME_duty` is another's `NAME`), and such that none of
/// `NAME`, `NAME_rig`, `NAME_levels`, `NAME_duty` and the include guard ([`c_guard`]) is an
/// identifier of the C API (`cartpole_policy.h`), which a board includes beside it.
pub fn check_c_name(name: &str) -> Result<()> {
    check_length(name)?;
    // The object is defined at file scope, where C reserves every name with a leading `_`
    // (C11 7.1.3) and C++ every one in the global namespace: the C library's own (`_exit`,
    // `_setjmp`, `_tolower`) among them, and whichever a later C library adds.
    if name.starts_with('_') {
        return Err(Error::Input(format!(
            "--name: expected a name starting with a letter, found {}: C reserves names \
             starting with `_` at file scope, where the header defines its object",
            quote(name)
        )));
    }
    let b = name.as_bytes();
    let ok = b.first().is_some_and(u8::is_ascii_alphabetic)
        && b.iter().all(|c| c.is_ascii_alphanumeric() || *c == b'_')
        && !C_KEYWORDS.contains(&name)
        && !CXX_KEYWORDS.contains(&name)
        && !name.ends_with("_t")
        && !name.ends_with("_rig")
        && !name.ends_with("_levels")
        && !name.ends_with("_duty");
    if !ok {
        return Err(Error::Input(format!(
            "--name: expected a C identifier (letters, digits, `_`, e.g. cartpole_policy; not \
             a C or C++ keyword, not ending in _t, _rig, _levels or _duty), found {}",
            quote(name)
        )));
    }
    // Every header's macros (include guards `CARTPOLE_POLICY_H_NAME`, `CARTPOLE_*_DEFINED`)
    // share the prefix: another export's guard as a name made the two headers fail together.
    if name.starts_with(MACRO_PREFIX) {
        return Err(Error::Input(format!(
            "--name: expected a name outside the headers' macros, found {} (exported headers \
             and cartpole_policy.h define macros beginning {MACRO_PREFIX})",
            quote(name)
        )));
    }
    if let Some(why) = c_library_use(name) {
        return Err(Error::Input(format!(
            "--name: expected a name the C library leaves to programs, found {} ({why})",
            quote(name)
        )));
    }
    let api = api_identifiers();
    let items = [
        name.to_string(),
        format!("{name}_rig"),
        format!("{name}_levels"),
        format!("{name}_duty"),
        c_guard(name),
    ];
    // The API's macros make names by pasting a shape on (`cartpole_mlp##S##_forward`): a name
    // in such a family is one of its declarations for some shape.
    if let Some(family) = api_families().find(|f| name.starts_with(f)) {
        return Err(Error::Input(format!(
            "--name: expected a name outside the C API's, found {} (cartpole_policy.h's macros \
             declare names beginning {family} for each network shape)",
            quote(name)
        )));
    }
    match items.into_iter().find(|id| api.contains(&id.as_str())) {
        None => Ok(()),
        Some(id) => Err(Error::Input(format!(
            "--name: expected a name whose header declares nothing of the C API's, found {} \
             (the header would define {id}, which cartpole_policy.h declares)",
            quote(name)
        ))),
    }
}

/// What every macro of the exported headers and of the C API's begins with.
const MACRO_PREFIX: &str = "CARTPOLE_";

/// The include guard of the header for the object `name`: the name as it is, so that names
/// differing only in case (C's are case-sensitive) give headers that compile together.
pub fn c_guard(name: &str) -> String {
    format!("CARTPOLE_POLICY_H_{name}")
}

/// The C API's header, whose identifiers an exported header must not define.
const API_HEADER: &str = include_str!("../../../capi/include/cartpole_policy.h");

/// The beginnings of the C API's pasted names: each identifier in its namespace that a `##`
/// follows in the header (`cartpole_mlp` of `cartpole_mlp##S##_forward`).
fn api_families() -> impl Iterator<Item = &'static str> {
    API_HEADER.match_indices("##").filter_map(|(at, _)| {
        let before = &API_HEADER[..at];
        let start = before
            .rfind(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .map_or(0, |i| i + 1);
        let id = &before[start..];
        (id.starts_with("cartpole_") || id.starts_with("CARTPOLE_")).then_some(id)
    })
}

/// The identifiers of the C API in its namespace (those starting `cartpole_` or `CARTPOLE_`,
/// outside comments): its functions, types, struct tags, macros and constants.
fn api_identifiers() -> Vec<&'static str> {
    let mut ids = Vec::new();
    let mut rest = API_HEADER;
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix("/*") {
            rest = r.split_once("*/").map_or("", |(_, after)| after);
        } else if let Some(r) = rest.strip_prefix("//") {
            rest = r.split_once('\n').map_or("", |(_, after)| after);
        } else if rest.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_') {
            let end = rest
                .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .unwrap_or(rest.len());
            let id = &rest[..end];
            if id.starts_with("cartpole_") || id.starts_with("CARTPOLE_") {
                ids.push(id);
            }
            rest = &rest[end..];
        } else {
            let skip = rest.chars().next().map_or(1, char::len_utf8);
            rest = &rest[skip..];
        }
    }
    ids
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_checked_for_each_language() {
        for ok in ["POLICY", "BALANCE_V2", "_P"] {
            check_rust_name(ok).unwrap();
        }
        for bad in ["policy", "2FAST", "", "_", "A-B", "POLICY;fn"] {
            let e = check_rust_name(bad).unwrap_err();
            assert!(e.is_input() && e.to_string().contains("--name"), "{bad}");
        }
        for ok in ["cartpole_policy", "P", "p_", "w64"] {
            check_c_name(ok).unwrap();
        }
        for bad in ["int", "static", "9a", "a b", "", "a;b"] {
            assert!(check_c_name(bad).is_err(), "{bad}");
        }
        for bad in [
            "_", "_p", "_X", "__x", "_exit", "_setjmp", "_tolower", "_longjmp",
        ] {
            let e = check_c_name(bad).unwrap_err();
            let shown = format!("found {}: C reserves names starting with `_`", quote(bad));
            assert!(e.is_input() && e.to_string().contains(&shown), "{e}");
        }
    }

    #[test]
    fn the_generated_gnu_names_are_sorted_for_their_binary_search() {
        let unsorted = gnu_library::GNU_NAMES.windows(2).find(|w| w[0] >= w[1]);
        assert_eq!(unsorted, None);
        for name in ["read", "fork", "mempcpy", "sincos", "qsort_r"] {
            let e = check_c_name(name).unwrap_err().to_string();
            assert!(e.contains("_GNU_SOURCE"), "{e}");
        }
    }

    #[test]
    fn a_long_bad_name_is_quoted_short() {
        let e = check_rust_name(&"x".repeat(100_000))
            .unwrap_err()
            .to_string();
        assert!(e.len() < 400, "{}", e.len());
    }

    #[test]
    fn c_names_that_clash_with_the_api_or_other_headers_are_refused() {
        let api = api_identifiers();
        for id in [
            "cartpole_controller_init",
            "cartpole_mlp64",
            "CARTPOLE_DUTY_MAX",
            "cartpole_rig",
        ] {
            assert!(api.contains(&id), "{id} missing from {api:?}");
        }
        assert!(
            !api.contains(&"cartpole_policy"),
            "a comment's word taken as an identifier"
        );
        for bad in [
            "cartpole_controller_init",
            "cartpole_controller_step",
            "CARTPOLE_DUTY_MAX",
            "cartpole_mlp16",
            "cartpole",
            "balance_rig",
            "balance_levels",
            "balance_duty",
            "int32_t",
            "class",
            "new",
            "this",
            "xor",
        ] {
            assert!(check_c_name(bad).is_err(), "{bad} accepted");
        }
        check_rust_name("RIG").unwrap_err();
        for ok in [
            "cartpole_policy",
            "cartpole_policy_int",
            "Balance",
            "balance",
        ] {
            check_c_name(ok).unwrap();
        }
        assert_ne!(c_guard("Balance"), c_guard("balance"));
    }
}

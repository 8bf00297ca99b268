//! The names the C library takes, which an exported header's object may not have: a macro
//! would replace the object's name before the compiler saw it, and a function or object of
//! the same name would clash with it. C11 7.1.3 reserves every name a standard header
//! declares once the header is included, and a program includes the standard headers beside
//! the policy's. Where the standard reserves a pattern (C11 7.31, future library directions)
//! the pattern is refused, not only today's names.

use super::posix_library::posix_library_use;

/// Why the C library takes `name`, if it does.
pub(super) fn c_library_use(name: &str) -> Option<String> {
    if stdint_macro(name) {
        return Some("a macro name of <stdint.h>, which the header includes".into());
    }
    if ["NULL", "offsetof", "unreachable"].contains(&name) {
        return Some(
            "a macro of <stddef.h>, which a program may include beside the header; NULL is \
             one of <stdio.h>, <stdlib.h> and <string.h> too"
                .into(),
        );
    }
    if name == "errno" {
        return Some(
            "the macro of <errno.h>, which a program may include beside the header".into(),
        );
    }
    let fixed = match name {
        "main" => Some("the function every C program defines, which the object would clash with"),
        "unix" | "linux" | "i386" => {
            Some("a macro the compilers' default GNU dialects predefine (-std=gnu11, gnu++17)")
        }
        "NDEBUG" => Some("the macro a release build defines (-DNDEBUG: every CMake Release build)"),
        _ => None,
    };
    if let Some(why) = fixed {
        return Some(why.into());
    }
    // A name's own header first: `EOF` is <stdio.h>'s, though <errno.h> reserves its form.
    if let Some(header) = listed(name).or_else(|| reserved_pattern(name)) {
        return Some(format!(
            "a name {header} declares or reserves, which a program may include beside the header"
        ));
    }
    let header = posix_library_use(name)?;
    Some(format!(
        "a name {header} declares in the GNU dialect C compilers default to (-std=gnu17), \
         from POSIX or the BSDs, which a program may include beside the header"
    ))
}

/// Whether `name` is a macro of `<stdint.h>`: C11 7.31.10 reserves names of `INT` or `UINT`
/// and `_MAX`, `_MIN` or `_C`, C23 adds `_WIDTH`; the limits of the types other headers
/// define besides.
fn stdint_macro(name: &str) -> bool {
    let int_limit = (name.starts_with("INT") || name.starts_with("UINT"))
        && ["_MAX", "_MIN", "_WIDTH", "_C"]
            .iter()
            .any(|end| name.ends_with(end));
    int_limit || STDINT_MACROS.contains(&name)
}

/// The macros of `<stdint.h>` outside its `INT` and `UINT` names: the limits of the types
/// other headers define, with C23's widths.
const STDINT_MACROS: [&str; 14] = [
    "PTRDIFF_MIN",
    "PTRDIFF_MAX",
    "PTRDIFF_WIDTH",
    "SIG_ATOMIC_MIN",
    "SIG_ATOMIC_MAX",
    "SIG_ATOMIC_WIDTH",
    "SIZE_MAX",
    "SIZE_WIDTH",
    "WCHAR_MIN",
    "WCHAR_MAX",
    "WCHAR_WIDTH",
    "WINT_MIN",
    "WINT_MAX",
    "WINT_WIDTH",
];

/// The header whose reserved pattern `name` falls in: a prefix, then a character of a class.
fn reserved_pattern(name: &str) -> Option<&'static str> {
    let upper = |c: u8| c.is_ascii_uppercase();
    let upper_or_digit = |c: u8| c.is_ascii_uppercase() || c.is_ascii_digit();
    let lower = |c: u8| c.is_ascii_lowercase();
    let lower_or_x = |c: u8| c.is_ascii_lowercase() || c == b'X';
    type Class = fn(u8) -> bool;
    // C11 7.31 unless said: errno's E macros, signal's, locale's, fenv's, inttypes' format
    // macros, wchar's wcs,
    // stdatomic's, threads', <math.h>'s FP_ (7.12), and POSIX <math.h>'s M_ constants
    // (M_PI), which GNU dialects define.
    let patterns: [(&str, Class, &str); 16] = [
        ("E", upper_or_digit, "<errno.h>"),
        ("SIG_", upper, "<signal.h>"),
        ("SIG", upper, "<signal.h>"),
        ("LC_", upper, "<locale.h>"),
        ("FE_", upper, "<fenv.h>"),
        ("PRI", lower_or_x, "<inttypes.h>"),
        ("SCN", lower_or_x, "<inttypes.h>"),
        ("wcs", lower, "<wchar.h>"),
        ("ATOMIC_", upper, "<stdatomic.h>"),
        ("atomic_", lower, "<stdatomic.h>"),
        ("memory_order_", lower, "<stdatomic.h>"),
        ("cnd_", lower, "<threads.h>"),
        ("mtx_", lower, "<threads.h>"),
        ("thrd_", lower, "<threads.h>"),
        ("tss_", lower, "<threads.h>"),
        ("FP_", upper, "<math.h>"),
    ];
    let b = name.as_bytes();
    let posix_math = name.starts_with("M_") && b.get(2).is_some_and(|&c| upper_or_digit(c));
    if posix_math {
        return Some("POSIX's <math.h>");
    }
    patterns.into_iter().find_map(|(prefix, class, header)| {
        let next = b.get(prefix.len()).copied();
        (name.starts_with(prefix) && next.is_some_and(class)).then_some(header)
    })
}

/// The header that lists `name` ([`LISTS`]), a limit of `<limits.h>` or `<float.h>`, or a
/// function of `<math.h>` or `<complex.h>` with its `f` and `l` forms.
fn listed(name: &str) -> Option<&'static str> {
    let limit = |prefixes: &str| {
        prefixes.split_whitespace().any(|p| {
            name.strip_prefix(p)
                .is_some_and(|rest| rest == "_MAX" || rest == "_MIN" || rest == "_WIDTH")
        })
    };
    if limit(LIMITS) || ["CHAR_BIT", "MB_LEN_MAX", "BOOL_WIDTH"].contains(&name) {
        return Some("<limits.h>");
    }
    if ["FLT_", "DBL_", "LDBL_"]
        .iter()
        .any(|p| name.starts_with(p))
        || name == "DECIMAL_DIG"
    {
        return Some("<float.h>");
    }
    for (header, functions) in [
        ("<math.h>", MATH_FUNCTIONS),
        ("<complex.h>", COMPLEX_FUNCTIONS),
    ] {
        if with_forms(name, functions) {
            return Some(header);
        }
    }
    LISTS
        .iter()
        .find(|(_, names)| names.split_whitespace().any(|n| n == name))
        .map(|(header, _)| *header)
}

/// Whether `name` is one of `functions` or its `f` (float) or `l` (long double) form.
pub(super) fn with_forms(name: &str, functions: &str) -> bool {
    let base = [name.strip_suffix('f'), name.strip_suffix('l')];
    functions
        .split_whitespace()
        .any(|f| f == name || base.contains(&Some(f)))
}

/// The types of `<limits.h>`, each with its `_MAX` and `_MIN` (C23: `_WIDTH`).
const LIMITS: &str = "CHAR SCHAR UCHAR SHRT USHRT INT UINT LONG ULONG LLONG ULLONG";

/// `<math.h>`'s functions, each with an `f` (float) and `l` (long double) form.
const MATH_FUNCTIONS: &str = "acos asin atan atan2 cos sin tan acosh asinh atanh cosh sinh \
    tanh exp exp2 expm1 frexp ilogb ldexp log log10 log1p log2 logb modf scalbn scalbln cbrt \
    fabs hypot pow sqrt erf erfc lgamma tgamma ceil floor nearbyint rint lrint llrint round \
    lround llround trunc fmod remainder remquo copysign nan nextafter nexttoward fdim fmax fmin \
    fma";

/// `<complex.h>`'s functions, each with an `f` and `l` form.
const COMPLEX_FUNCTIONS: &str = "cacos casin catan ccos csin ctan cacosh casinh catanh ccosh \
    csinh ctanh cexp clog cabs cpow csqrt carg cimag conj cproj creal";

/// The other names each standard header declares, outside the patterns above, keywords, and
/// names reserved by their form (a leading `_`, a `_t` ending).
const LISTS: [(&str, &str); 20] = [
    ("<assert.h>", "assert"),
    // Today's is/to and str/mem functions by name: C11 7.31 reserves every lowercase name of
    // those forms for the library's future, but C23 leaves them to programs until a library
    // declares one, and `torque` or `string` are names a rig's code takes.
    (
        "<ctype.h>",
        "isalnum isalpha isblank iscntrl isdigit isgraph islower isprint ispunct isspace \
         isupper isxdigit tolower toupper",
    ),
    (
        "<string.h>",
        "memcpy memmove strcpy strncpy strcat strncat memcmp strcmp strcoll strncmp strxfrm \
         memchr strchr strcspn strpbrk strrchr strspn strstr strtok memset strerror strlen",
    ),
    ("<complex.h>", "complex imaginary I CMPLX CMPLXF CMPLXL"),
    (
        "<fenv.h>",
        "feclearexcept fegetexceptflag feraiseexcept fesetexceptflag fetestexcept fegetround \
         fesetround fegetenv feholdexcept fesetenv feupdateenv",
    ),
    ("<inttypes.h>", "imaxabs imaxdiv strtoimax strtoumax"),
    ("<locale.h>", "setlocale localeconv"),
    (
        "<math.h>",
        "HUGE_VAL HUGE_VALF HUGE_VALL INFINITY NAN MATH_ERRNO MATH_ERREXCEPT \
         math_errhandling fpclassify signbit isfinite isinf isnan isnormal isgreater \
         isgreaterequal isless islessequal islessgreater isunordered",
    ),
    ("<setjmp.h>", "setjmp longjmp jmp_buf"),
    ("<signal.h>", "signal raise"),
    ("<stdarg.h>", "va_list va_start va_arg va_end va_copy"),
    ("<stdatomic.h>", "kill_dependency memory_order"),
    (
        "<stdio.h>",
        "FILE EOF BUFSIZ FOPEN_MAX FILENAME_MAX L_tmpnam SEEK_CUR SEEK_END SEEK_SET TMP_MAX \
         stderr stdin stdout remove rename tmpfile tmpnam fclose fflush fopen freopen setbuf \
         setvbuf fprintf fscanf printf scanf snprintf sprintf sscanf vfprintf vfscanf vprintf \
         vscanf vsnprintf vsprintf vsscanf fgetc fgets fputc fputs getc getchar gets putc \
         putchar puts ungetc fread fwrite fgetpos fseek fsetpos ftell rewind clearerr feof \
         ferror perror",
    ),
    (
        "<stdlib.h>",
        "EXIT_FAILURE EXIT_SUCCESS MB_CUR_MAX RAND_MAX atof atoi atol atoll strtod strtof \
         strtold strtol strtoll strtoul strtoull rand srand aligned_alloc calloc free malloc \
         realloc abort atexit at_quick_exit exit quick_exit getenv system bsearch qsort abs \
         labs llabs div ldiv lldiv mblen mbtowc wctomb mbstowcs wcstombs",
    ),
    ("<stdnoreturn.h>", "noreturn"),
    (
        "<threads.h>",
        "ONCE_FLAG_INIT TSS_DTOR_ITERATIONS call_once once_flag",
    ),
    (
        "<time.h>",
        "CLOCKS_PER_SEC TIME_UTC clock difftime mktime time timespec_get asctime ctime gmtime \
         localtime strftime",
    ),
    ("<uchar.h>", "mbrtoc16 c16rtomb mbrtoc32 c32rtomb"),
    (
        "<wchar.h>",
        "WEOF fwprintf fwscanf swprintf swscanf vfwprintf vfwscanf vswprintf vswscanf vwprintf \
         vwscanf wprintf wscanf fgetwc fgetws fputwc fputws fwide getwc getwchar putwc putwchar \
         ungetwc wmemchr wmemcmp wmemcpy wmemmove wmemset btowc wctob mbsinit mbrlen mbrtowc \
         wcrtomb mbsrtowcs wcsrtombs",
    ),
    (
        "<wctype.h>",
        "wctype wctrans iswalnum iswalpha iswblank iswcntrl iswdigit iswgraph iswlower \
         iswprint iswpunct iswspace iswupper iswxdigit iswctype towlower towupper towctrans",
    ),
];

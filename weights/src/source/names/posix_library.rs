//! The names the C library's standard headers declare beyond C11's in the dialect C compilers
//! default to: GCC's and Clang's `-std=gnu17` asks glibc for POSIX's, X/Open's and the BSD
//! and System V extensions (`_DEFAULT_SOURCE`), so a program built so sees `y0`, `random`,
//! `fileno` or `popen` beside the exported header, and an object of that name fails to
//! compile there though it compiles under `-std=c11`. The many more names the same headers
//! declare under `_GNU_SOURCE`, which g++ defines for every C++ program on glibc (`mempcpy`,
//! `sincos`, `qsort_r`, `read`, `fork`), are glibc's whole extension surface: not written by
//! hand but asked of the compilers (`gnu_library.rs`).
//! Each is listed under the C11 header that declares it (`<stdlib.h>` brings
//! `<sys/types.h>`, `<sys/select.h>`, `<endian.h>` and the wait macros); where POSIX
//! reserves a prefix before a capital for a header's macros (XBD 2.2.2) the prefix is
//! refused, but not its `_MAX` ending for `<limits.h>`: `MY_SIZE_MAX` compiles beside them.

use super::c_library::with_forms;

/// The header that declares `name` in `-std=gnu17`, if one does.
pub(super) fn posix_library_use(name: &str) -> Option<&'static str> {
    if with_forms(name, MATH_FUNCTIONS) {
        return Some("<math.h>");
    }
    let b = name.as_bytes();
    let pattern = PATTERNS.iter().find(|(prefix, _)| {
        name.starts_with(prefix) && b.get(prefix.len()).is_some_and(u8::is_ascii_uppercase)
    });
    if let Some((_, header)) = pattern {
        return Some(header);
    }
    LISTS
        .iter()
        .find(|(_, names)| names.split_whitespace().any(|n| n == name))
        .map(|(header, _)| *header)
}

/// `<math.h>`'s functions from POSIX and the BSDs, each with an `f` and `l` form.
const MATH_FUNCTIONS: &str = "j0 j1 jn y0 y1 yn gamma drem finite scalb significand isinf isnan";

/// The prefixes POSIX reserves for a header's macros, each before a capital: `<signal.h>`'s
/// signal codes and flags, `<time.h>`'s clocks and timer flags.
const PATTERNS: [(&str, &str); 13] = [
    ("BUS_", "<signal.h>"),
    ("CLD_", "<signal.h>"),
    ("FPE_", "<signal.h>"),
    ("ILL_", "<signal.h>"),
    ("POLL_", "<signal.h>"),
    ("SA_", "<signal.h>"),
    ("SEGV_", "<signal.h>"),
    ("SI_", "<signal.h>"),
    ("SIGEV_", "<signal.h>"),
    ("SS_", "<signal.h>"),
    ("TRAP_", "<signal.h>"),
    ("CLOCK_", "<time.h>"),
    ("TIMER_", "<time.h>"),
];

/// The other names each header declares in `-std=gnu17` beyond C11's, outside names
/// reserved by their form (a leading `_`, a `_t` ending).
const LISTS: [(&str, &str); 12] = [
    ("<math.h>", "lgamma_r lgammaf_r lgammal_r signgam"),
    (
        "<limits.h>",
        "AIO_PRIO_DELTA_MAX BC_BASE_MAX BC_DIM_MAX BC_SCALE_MAX BC_STRING_MAX \
         CHARCLASS_NAME_MAX COLL_WEIGHTS_MAX DELAYTIMER_MAX EXPR_NEST_MAX HOST_NAME_MAX \
         LINE_MAX LOGIN_NAME_MAX MQ_PRIO_MAX NAME_MAX NGROUPS_MAX PATH_MAX PTHREAD_KEYS_MAX \
         RE_DUP_MAX RTSIG_MAX SEM_VALUE_MAX SSIZE_MAX TTY_NAME_MAX XATTR_LIST_MAX \
         XATTR_NAME_MAX XATTR_SIZE_MAX MAX_CANON MAX_INPUT PIPE_BUF \
         PTHREAD_DESTRUCTOR_ITERATIONS PTHREAD_STACK_MIN",
    ),
    (
        "<stdlib.h>",
        "a64l alloca arc4random arc4random_buf arc4random_uniform clearenv drand48 drand48_r \
         ecvt ecvt_r erand48 erand48_r fcvt fcvt_r gcvt getloadavg getsubopt initstate \
         initstate_r jrand48 jrand48_r l64a lcong48 lcong48_r lrand48 lrand48_r mkdtemp \
         mkstemp mkstemps mktemp mrand48 mrand48_r nrand48 nrand48_r on_exit posix_memalign \
         putenv qecvt qecvt_r qfcvt qfcvt_r qgcvt rand_r random random_r reallocarray \
         realpath rpmatch seed48 seed48_r setenv setstate setstate_r srand48 srand48_r \
         srandom srandom_r strtoq strtouq unsetenv valloc select pselect fd_mask fd_set \
         FD_SETSIZE NFDBITS u_char u_short u_int u_long ushort uint ulong BIG_ENDIAN \
         LITTLE_ENDIAN PDP_ENDIAN BYTE_ORDER be16toh be32toh be64toh htobe16 htobe32 htobe64 \
         htole16 htole32 htole64 le16toh le32toh le64toh WCONTINUED WEXITED WEXITSTATUS \
         WIFCONTINUED WIFEXITED WIFSIGNALED WIFSTOPPED WNOHANG WNOWAIT WSTOPPED WSTOPSIG \
         WTERMSIG WUNTRACED",
    ),
    (
        "<stdio.h>",
        "ctermid dprintf fdopen fileno flockfile fmemopen fseeko ftello ftrylockfile \
         funlockfile getdelim getline getw open_memstream pclose popen putw renameat \
         setbuffer setlinebuf tempnam tmpnam_r vdprintf clearerr_unlocked feof_unlocked \
         ferror_unlocked fflush_unlocked fgetc_unlocked fileno_unlocked fputc_unlocked \
         fread_unlocked fwrite_unlocked getc_unlocked getchar_unlocked putc_unlocked \
         putchar_unlocked P_tmpdir L_ctermid",
    ),
    (
        "<string.h>",
        "bcmp bcopy bzero explicit_bzero ffs ffsl ffsll index rindex memccpy stpcpy stpncpy \
         strcasecmp strcasecmp_l strncasecmp strncasecmp_l strcoll_l strxfrm_l strdup \
         strndup strerror_l strerror_r strlcat strlcpy strnlen strsep strsignal strtok_r",
    ),
    (
        "<ctype.h>",
        "isascii toascii isascii_l toascii_l isalnum_l isalpha_l isblank_l iscntrl_l \
         isdigit_l isgraph_l islower_l isprint_l ispunct_l isspace_l isupper_l isxdigit_l \
         tolower_l toupper_l",
    ),
    (
        "<wctype.h>",
        "iswalnum_l iswalpha_l iswblank_l iswcntrl_l iswctype_l iswdigit_l iswgraph_l \
         iswlower_l iswprint_l iswpunct_l iswspace_l iswupper_l iswxdigit_l towctrans_l \
         towlower_l towupper_l wctrans_l wctype_l",
    ),
    ("<wchar.h>", "mbsnrtowcs wcpcpy wcpncpy open_wmemstream"),
    ("<locale.h>", "duplocale freelocale newlocale uselocale"),
    (
        "<time.h>",
        "asctime_r ctime_r gmtime_r localtime_r clock_getcpuclockid clock_getres \
         clock_gettime clock_nanosleep clock_settime dysize nanosleep strftime_l timegm \
         timelocal timer_create timer_delete timer_getoverrun timer_gettime timer_settime \
         tzset tzname timezone daylight",
    ),
    (
        "<signal.h>",
        "gsignal kill killpg psiginfo psignal pthread_kill pthread_sigmask sigaction \
         sigaddset sigaltstack sigblock sigdelset sigemptyset sigfillset siggetmask \
         siginterrupt sigismember sigpending sigprocmask sigqueue sigreturn sigsetmask \
         sigstack sigsuspend sigtimedwait sigwait sigwaitinfo ssignal sigmask NSIG NGREG \
         MINSIGSTKSZ sa_handler sa_sigaction si_addr si_addr_lsb si_arch si_band \
         si_call_addr si_fd si_int si_lower si_overrun si_pid si_pkey si_ptr si_status \
         si_stime si_syscall si_timerid si_uid si_upper si_utime si_value \
         sigev_notify_attributes sigev_notify_function",
    ),
    ("<setjmp.h>", "sigjmp_buf siglongjmp sigsetjmp"),
];

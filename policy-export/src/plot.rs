//! Plot set-up shared by every figure the project draws: a font compiled into the binary,
//! so PNGs render on machines without any system fonts.

use std::sync::OnceLock;

use anyhow::{Result, bail};
use plotters::style::{FontStyle, register_font};

/// DejaVu Sans (Bitstream Vera licence, `assets/fonts/DejaVuSans-LICENSE`).
static DEJAVU_SANS: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// The family name figures use.
pub const FONT: &str = "sans-serif";

/// Registers the bundled font under [`FONT`]; call before drawing any text. Idempotent.
pub fn ensure_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        [FontStyle::Normal, FontStyle::Bold]
            .into_iter()
            .all(|style| register_font(FONT, style, DEJAVU_SANS).is_ok())
    });
    if !ok {
        bail!("the bundled font assets/fonts/DejaVuSans.ttf does not parse");
    }
    Ok(())
}

//! `config_keys!`, which turns the one list of keys in the parent module into everything that
//! names every key: the parent module's documentation says what it generates and why.

use serde::{Deserialize, Deserializer};

/// Deserialises a key that is present: `None` comes only from its absence (through
/// `#[serde(default)]`), so a JSON `null` is refused as the key's type would refuse it.
pub(super) fn present<'de, D, T>(d: D) -> Result<Option<T>, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de>,
{
    T::deserialize(d).map(Some)
}

/// Generates, from one declaration per key, the `Config` struct, `Config::paper`, the
/// `Overrides` flags and their overlay, the reading of files that lack keys, and `LIMITS`.
macro_rules! config_keys {
    (
        $(#[doc = $doc:literal])*
        pub struct Config {
            $(
                $(#[doc = $key_doc:literal])*
                $(#[serde($absent:ident)])?
                $(#[flag($flag:ident)])?
                $key:ident: $ty:ty = $paper:expr $(, limit $limit:expr)?;
            )*
        }
    ) => {
        $(#[doc = $doc])*
        #[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
        #[serde(try_from = "Overrides")]
        pub struct Config {
            $($(#[doc = $key_doc])* pub $key: $ty,)*
        }

        impl Config {
            /// The paper's Table 2 and section 3: every key at the default it is declared with.
            pub fn paper() -> Config {
                Config { $($key: $paper,)* }
            }
        }

        config_keys!(@overrides [] $($key: $ty $(, $flag)?;)*);

        impl Overrides {
            /// Sets the keys that are set here.
            pub fn apply(&self, c: &mut Config) {
                $(if let Some(v) = &self.$key {
                    c.$key.clone_from(v);
                })*
            }
        }

        /// A file that lacks a key marked `#[serde(default)]` (one added after files were
        /// first written) gets the key's paper value; lacking any other key is an error.
        impl TryFrom<Overrides> for Config {
            type Error = String;

            fn try_from(o: Overrides) -> Result<Config, String> {
                Ok(Config {
                    $($key: match o.$key {
                        Some(v) => v,
                        None => config_keys!(@absent $key $(, $absent)?, $paper),
                    },)*
                })
            }
        }

        /// Every key's own limit, in the order the keys are declared.
        pub const LIMITS: &[KeyLimit] = &[
            $($(KeyLimit {
                key: stringify!($key),
                limit: $limit,
                get: |c| Value::from(&c.$key),
            },)?)*
        ];
    };
    // `Overrides`, a field a key: the flag `--key-with-dashes`, but none for a key marked
    // `#[flag(file)]`, whose flag the command declares, taking the file whose text is the
    // key's value (a path need not be text, so the flag cannot be the value's type).
    (@overrides [$($field:tt)*] $key:ident: $ty:ty; $($rest:tt)*) => {
        config_keys!(@overrides [$($field)* #[arg(long)] $key: $ty;] $($rest)*);
    };
    (@overrides [$($field:tt)*] $key:ident: $ty:ty, file; $($rest:tt)*) => {
        config_keys!(@overrides [$($field)* #[arg(skip)] $key: $ty;] $($rest)*);
    };
    (@overrides [$(#[$arg:meta] $key:ident: $ty:ty;)*]) => {
        /// Some keys of a configuration, each set or absent: the command-line flags, one
        /// `--key-with-dashes` per key (see [`Config`] for their meaning) but for the keys
        /// whose flag names a file, and what a file is read as before [`Config`] fills in
        /// the keys it may lack.
        #[derive(Debug, Deserialize, clap::Args)]
        #[serde(deny_unknown_fields)]
        pub struct Overrides {
            $(
                #[$arg]
                #[serde(default, deserialize_with = "keys::present")]
                pub $key: Option<$ty>,
            )*
        }
    };
    (@absent $key:ident, default, $paper:expr) => {
        $paper
    };
    (@absent $key:ident, $paper:expr) => {
        return Err(format!("missing field `{}`", stringify!($key)))
    };
}

pub(super) use config_keys;

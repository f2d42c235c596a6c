//! `code_table!`: a small code enum declared once, as a table (in the spirit
//! of smoltcp's `enum_with_unknown!`). A row is a variant, its doc comment
//! and, where the code is a value of a format rather than a position, its
//! code; everything else is derived from the row, so no list and no name is
//! kept by hand:
//! - `ALL`, the rows in table order;
//! - `code` and `from_code` (a row without `= code` takes the next one, as
//!   Rust's own discriminants do: a table of a format's codes gives its
//!   first code, and a new row goes at the end);
//! - `name`, the variant in snake_case (metric labels, JSON, the dissector);
//! - `describe`, the doc comment: the meaning for a person.
//!
//! ```
//! sagebrush_protocol::code_table! {
//!     /// Why a thing happened.
//!     pub enum Why: u8 {
//!         /// someone asked for it
//!         Asked = 1,
//!         /// it ran out
//!         /// of time
//!         RanLate,
//!     }
//! }
//! assert_eq!(Why::ALL, [Why::Asked, Why::RanLate]);
//! assert_eq!(Why::from_code(2), Some(Why::RanLate));
//! assert_eq!((Why::RanLate.code(), Why::RanLate.name()), (2, "ran_late"));
//! assert_eq!(Why::RanLate.describe(), "it ran out of time");
//! ```

/// Declares a code enum from its rows (see the module documentation).
#[macro_export]
macro_rules! code_table {
    (
        $(#[$meta:meta])*
        $vis:vis enum $Enum:ident: $repr:ty {
            $( $(#[doc = $doc:literal])+ $Variant:ident $(= $code:literal)?, )+
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        #[repr($repr)]
        $vis enum $Enum {
            $( $(#[doc = $doc])+ $Variant $(= $code)?, )+
        }

        impl $Enum {
            /// Every row, in table order.
            pub const ALL: [$Enum; [$(stringify!($Variant)),+].len()] = [$($Enum::$Variant),+];

            /// The row's code.
            pub const fn code(self) -> $repr {
                self as $repr
            }

            /// The row whose code is `code`.
            pub const fn from_code(code: $repr) -> Option<Self> {
                match code {
                    $( c if c == $Enum::$Variant as $repr => Some($Enum::$Variant), )+
                    _ => None,
                }
            }

            /// The variant's name in snake_case (metric labels, JSON).
            pub const fn name(self) -> &'static str {
                match self {
                    $( $Enum::$Variant => $crate::snake_case!($Variant), )+
                }
            }

            /// What it means, for a person: the row's doc comment.
            pub const fn describe(self) -> &'static str {
                match self {
                    $( $Enum::$Variant => concat!($($doc),+).trim_ascii(), )+
                }
            }
        }
    };
}

/// The identifier `$name` (CamelCase) in snake_case, as a `&'static str`
/// computed at compile time.
#[doc(hidden)]
#[macro_export]
macro_rules! snake_case {
    ($name:ident) => {{
        const CAMEL: &str = stringify!($name);
        const BYTES: [u8; $crate::snake_case_len(CAMEL)] = $crate::snake_case_bytes(CAMEL);
        const NAME: &str = match core::str::from_utf8(&BYTES) {
            Ok(name) => name,
            Err(_) => panic!("an identifier made of ASCII letters and digits"),
        };
        NAME
    }};
}

/// Bytes of `camel` in snake_case: one more per capital after the first.
#[doc(hidden)]
pub const fn snake_case_len(camel: &str) -> usize {
    let bytes = camel.as_bytes();
    let mut len = bytes.len();
    let mut i = 1;
    while i < bytes.len() {
        len += bytes[i].is_ascii_uppercase() as usize;
        i += 1;
    }
    len
}

/// `camel` in snake_case (`N` from [`snake_case_len`]).
#[doc(hidden)]
pub const fn snake_case_bytes<const N: usize>(camel: &str) -> [u8; N] {
    let bytes = camel.as_bytes();
    let mut out = [0u8; N];
    let (mut i, mut o) = (0, 0);
    while i < bytes.len() {
        let b = bytes[i];
        if b.is_ascii_uppercase() && i > 0 {
            out[o] = b'_';
            o += 1;
        }
        out[o] = b.to_ascii_lowercase();
        o += 1;
        i += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    crate::code_table! {
        /// A table of every form a row takes.
        enum Sample: u8 {
            /// one word
            Frame = 3,
            /// the next code, two words
            BadChecksum,
            /// an acronym-like name
            /// over two lines
            NoACK = 9,
        }
    }

    #[test]
    fn names_codes_and_meanings_come_from_the_rows() {
        assert_eq!(Sample::ALL.map(Sample::code), [3, 4, 9]);
        assert_eq!(Sample::ALL.map(Sample::name), ["frame", "bad_checksum", "no_a_c_k"]);
        assert_eq!(Sample::NoACK.describe(), "an acronym-like name over two lines");
        assert_eq!(Sample::from_code(4), Some(Sample::BadChecksum));
        assert_eq!(Sample::from_code(5), None);
    }
}

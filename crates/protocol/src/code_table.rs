//! `code_table!`: a small code enum declared once, as a table (in the spirit
//! of smoltcp's `enum_with_unknown!`). Each row is a variant with its code,
//! its short snake_case name and its meaning for a person; `ALL`, `code`,
//! `from_code`, `name` and `describe` are generated from the rows, so no
//! list is kept by hand. The meaning also documents the variant, so a row
//! needs no doc comment of its own.
//!
//! ```
//! sagebrush_protocol::code_table! {
//!     /// Why a thing happened.
//!     #[derive(Clone, Copy, Debug, PartialEq, Eq)]
//!     pub enum Why: u8 {
//!         Asked = 1, "asked", "someone asked for it";
//!         Late = 2, "late", "it ran out of time";
//!     }
//! }
//! assert_eq!(Why::ALL, [Why::Asked, Why::Late]);
//! assert_eq!(Why::from_code(2), Some(Why::Late));
//! assert_eq!((Why::Late.code(), Why::Late.name()), (2, "late"));
//! assert_eq!(Why::Asked.describe(), "someone asked for it");
//! ```

/// Declares a code enum from its rows (see the module documentation).
#[macro_export]
macro_rules! code_table {
    (
        $(#[$meta:meta])*
        $vis:vis enum $Enum:ident: $repr:ty {
            $( $(#[$doc:meta])* $Variant:ident = $code:literal, $name:literal, $meaning:literal; )+
        }
    ) => {
        $(#[$meta])*
        #[repr($repr)]
        $vis enum $Enum {
            $(
                $(#[$doc])*
                #[doc = concat!("\n\nMeaning: ", $meaning, ".")]
                $Variant = $code,
            )+
        }

        impl $Enum {
            /// Every row, in table order.
            pub const ALL: [$Enum; [$($code),+].len()] = [$($Enum::$Variant),+];

            /// The row's code.
            pub const fn code(self) -> $repr {
                self as $repr
            }

            /// The row whose code is `code`.
            pub const fn from_code(code: $repr) -> Option<Self> {
                match code {
                    $( $code => Some($Enum::$Variant), )+
                    _ => None,
                }
            }

            /// A short snake_case name (metric labels, JSON).
            pub const fn name(self) -> &'static str {
                match self {
                    $( $Enum::$Variant => $name, )+
                }
            }

            /// What it means, for a person.
            pub const fn describe(self) -> &'static str {
                match self {
                    $( $Enum::$Variant => $meaning, )+
                }
            }
        }
    };
}

//! What the firmware counts, one definition per group: [`counters!`](crate::counters!) makes
//! the struct, its names and its lookup by index, and from those the
//! command port lists each group (`:~C<g>#`, `port::interpreter`) and the
//! log writes each change (the binary's `firmware::log`), so a counter added
//! to its group's definition reaches both.

/// A group of counters read by index: the port's lists and the log.
pub trait Counters {
    /// Each counter's name, in index order, as the port and the log give it.
    const NAMES: &'static [&'static str];

    /// Counter `index`: its name and value.
    fn get(&self, index: usize) -> Option<(&'static str, u32)>;
}

/// A struct of `u32` counters (wrapping or saturating as their writers
/// choose) with [`Counters`]: `counters! { /// docs  pub struct Name {
/// /// docs  field, ... } }`, or `pub struct Name("prefix_")` to give
/// every name a prefix on the port and in the log.
#[macro_export]
macro_rules! counters {
    (
        $(#[$meta:meta])*
        pub struct $name:ident {
            $( $(#[$field_meta:meta])* $field:ident ),* $(,)?
        }
    ) => {
        $crate::counters! {
            $(#[$meta])*
            pub struct $name("") {
                $( $(#[$field_meta])* $field, )*
            }
        }
    };
    (
        $(#[$meta:meta])*
        pub struct $name:ident($prefix:literal) {
            $( $(#[$field_meta:meta])* $field:ident ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        pub struct $name {
            $( $(#[$field_meta])* pub $field: u32, )*
        }

        impl $crate::counters::Counters for $name {
            const NAMES: &'static [&'static str] = &[$(concat!($prefix, stringify!($field))),*];

            fn get(&self, index: usize) -> Option<(&'static str, u32)> {
                let values = [$(self.$field),*];
                Some((*Self::NAMES.get(index)?, *values.get(index)?))
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::Counters;

    crate::counters! {
        /// Two counters.
        pub struct Two("two_") {
            /// The first.
            first,
            second,
        }
    }

    #[test]
    fn each_counter_by_index_with_its_name() {
        let c = Two {
            first: 3,
            second: 5,
        };
        assert_eq!(Two::NAMES, &["two_first", "two_second"]);
        assert_eq!(c.get(0), Some(("two_first", 3)));
        assert_eq!(c.get(1), Some(("two_second", 5)));
        assert_eq!(c.get(2), None);
    }
}

//! Building the model's state where it lives. The model is about 55 KiB in
//! `f32`; a constructor that returns it by value makes LLVM build it in a
//! temporary on the stack and copy it into the firmware's static, which
//! once took a 54 KB stack frame at start-up (docs/firmware.md). The
//! `init` functions of the large types instead write each field through a
//! pointer into the destination, the arrays element by element; their
//! `new` is `init` on a local slot.

use core::mem::MaybeUninit;

/// `&mut MaybeUninit<F>` for the field `$field` of the `&mut
/// MaybeUninit<T>` `$slot`: a place to write it, nothing is read.
macro_rules! uninit_field {
    ($slot:expr, $field:ident) => {{
        let whole = $slot.as_mut_ptr();
        // SAFETY: `addr_of_mut!` makes a pointer to the field without
        // reading it or making a reference to the uninitialised whole; the
        // field lies inside the slot, with its own type and alignment.
        unsafe { $crate::model::in_place::as_uninit(core::ptr::addr_of_mut!((*whole).$field)) }
    }};
}
pub(crate) use uninit_field;

/// Writes every field of the `&mut MaybeUninit<Self>` `$slot`, in the
/// order given, and returns it as `&mut Self`: `field = value` writes the
/// value, `field in init` calls `init(&mut MaybeUninit<Field>)` (a large
/// field's own in-place `init`, or [`fill`]). Used inside the type's
/// `impl`. The compiler checks that the list names every field of `Self`
/// once: the same list is a struct literal in a closure that is never
/// called (it makes no code), so a field added to the type and not here
/// fails to build instead of being read uninitialised.
macro_rules! init_fields {
    ($slot:expr, Self { $( $field:ident $how:tt $value:expr ),* $(,)? }) => {{
        let slot = $slot;
        $( $crate::model::in_place::init_fields!(@one slot, $field $how $value); )*
        #[allow(unreachable_code, clippy::empty_loop)]
        let _every_field_once = || Self { $( $field: loop {} ),* };
        // SAFETY: every field of `Self` was written above: the closure's
        // struct literal, checked by the compiler, names each one once.
        unsafe { slot.assume_init_mut() }
    }};
    (@one $slot:ident, $field:ident = $value:expr) => {
        $crate::model::in_place::uninit_field!($slot, $field).write($value)
    };
    (@one $slot:ident, $field:ident in $init:expr) => {
        ($init)($crate::model::in_place::uninit_field!($slot, $field))
    };
}
pub(crate) use init_fields;

/// The place behind `field` as a `MaybeUninit` to write.
///
/// # Safety
/// `field` points to a place of type `F`, valid for writes and not
/// otherwise borrowed for `'a` (a field of a `&mut MaybeUninit` slot).
pub(crate) unsafe fn as_uninit<'a, F>(field: *mut F) -> &'a mut MaybeUninit<F> {
    // SAFETY: MaybeUninit<F> has the layout of F; the caller vouches for
    // the place.
    unsafe { &mut *field.cast::<MaybeUninit<F>>() }
}

/// Writes `value` into every element of the array in `slot`, without an
/// array temporary.
pub(crate) fn fill<T: Copy, const L: usize>(slot: &mut MaybeUninit<[T; L]>, value: T) {
    // SAFETY: [MaybeUninit<T>; L] has the layout of MaybeUninit<[T; L]>,
    // and any bit pattern (initialised or not) is valid for it.
    let elements = unsafe { &mut *slot.as_mut_ptr().cast::<[MaybeUninit<T>; L]>() };
    for e in elements {
        e.write(value);
    }
}

/// `init(slot)`, then the value: the by-value constructor of a type built
/// in place (for the host and the tests; the firmware keeps `init`).
pub(crate) fn build<T>(init: impl for<'a> FnOnce(&'a mut MaybeUninit<T>) -> &'a mut T) -> T {
    let mut slot = MaybeUninit::uninit();
    init(&mut slot);
    // SAFETY: `init` returned the slot as initialised (each type's `init`
    // writes every field before its `assume_init_mut`).
    unsafe { slot.assume_init() }
}

//! The arena the element trees of a load live in, kept per thread between loads.
//!
//! A model is loaded again and again while it is drawn (the studio checks it on every change),
//! and a tree of fresh pages costs more to fault in than to read. So the arena of the last load
//! on a thread is emptied and kept for the next, unless it grew past [`KEEP`].

use std::cell::Cell;

use bumpalo::Bump;

/// The largest arena kept between loads (a 10,000-node model's tree is about 10 MB).
const KEEP: usize = 32 << 20;

thread_local! {
    static KEPT: Cell<Option<Bump>> = const { Cell::new(None) };
}

/// An empty arena: the one this thread kept, or a new one.
pub(crate) fn take() -> Bump {
    KEPT.take().unwrap_or_default()
}

/// Empties an arena whose trees are gone and keeps it for the thread's next load.
pub(crate) fn give_back(mut bump: Bump) {
    bump.reset();
    if bump.allocated_bytes() <= KEEP {
        KEPT.set(Some(bump));
    }
}

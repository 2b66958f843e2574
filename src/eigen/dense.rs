//! Dense reference solver (under construction).

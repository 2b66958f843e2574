//! LOBPCG (under construction).

//! Small discrete filters: first order and biquad sections.

//! Campbell diagrams and order slices from a speed channel.

//! Frequency-response estimate H1 with coherence between two channels.

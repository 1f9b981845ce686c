//! Short-time Fourier transform and spectrogram.

"""scipy's side of the STFT benchmark (crates/strainwave-analysis/benches/stft.rs).

Usage: stft_scipy.py SIGNAL.f64 FS NPERSEG NOVERLAP {spectrogram,stft} ITERATIONS

Loads the raw little-endian float64 signal, runs the transform ITERATIONS times with
strainwave's conventions (periodic Hann, constant detrend, no boundary extension or
padding) and prints one JSON line: the elapsed seconds of the transforms alone (loading
and imports excluded) and a checksum of the last result for the benchmark to compare
with its own:

- `spectrogram`: scipy.signal.spectrogram(mode='psd', scaling='density'); checksum
  Σ Sxx (strainwave `stft::spectrogram`).
- `stft`: scipy.signal.stft(detrend='constant', boundary=None, padded=False); checksum
  Σ |Zxx| (strainwave `stft::stft` is the same with the one-sided factor 2 off DC and
  Nyquist, which the benchmark applies before comparing).

Exit status 3 (and a message on stderr) when numpy or scipy is missing.
"""

import json
import sys
import time


def main(argv):
    if len(argv) != 7:
        sys.stderr.write(__doc__)
        return 2
    try:
        import numpy as np
        from scipy import signal
    except ImportError as e:
        sys.stderr.write(f"stft_scipy.py: {e}\n")
        return 3
    path, fs, nperseg, noverlap, kind, iterations = argv[1:]
    fs, nperseg, noverlap, iterations = float(fs), int(nperseg), int(noverlap), int(iterations)
    x = np.fromfile(path, dtype="<f8")
    common = dict(fs=fs, window="hann", nperseg=nperseg, noverlap=noverlap, detrend="constant")
    if kind == "spectrogram":

        def run():
            return signal.spectrogram(x, scaling="density", mode="psd", **common)[2]

        def checksum(r):
            return float(np.sum(r))

    elif kind == "stft":

        def run():
            return signal.stft(x, boundary=None, padded=False, **common)[2]

        def checksum(r):
            return float(np.sum(np.abs(r)))

    else:
        sys.stderr.write(f"stft_scipy.py: unknown transform `{kind}`\n")
        return 2
    result = None
    t0 = time.perf_counter()
    for _ in range(iterations):
        result = run()
    seconds = time.perf_counter() - t0
    print(json.dumps({"seconds": seconds, "checksum": checksum(result), "frames": int(result.shape[-1])}))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

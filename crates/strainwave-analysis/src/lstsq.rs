//! Linear least squares by Householder QR (never the normal equations), with rank detection.

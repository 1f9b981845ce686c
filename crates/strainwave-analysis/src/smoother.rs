//! Fixed-interval (Rauch–Tung–Striebel) smoother on the ripple canceller's model.

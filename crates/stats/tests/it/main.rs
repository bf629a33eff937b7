//! Integration tests of fogline-stats: golden values from SciPy / scikit-learn, and
//! property tests.

#![allow(clippy::unwrap_used)]

mod gmm;
mod golden;
mod props;

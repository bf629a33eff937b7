//! Integration tests of fogline-stats: golden values from SciPy / scikit-learn, and
//! property tests.

mod gmm;
mod golden;
mod props;

//! MIS tests (below).

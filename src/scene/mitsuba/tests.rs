//! End-to-end tests of the XML loader on small scenes written to a temporary folder.

use super::*;

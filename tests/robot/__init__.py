"""Tests of the reference robot (a package, so module names cannot clash with other test folders)."""

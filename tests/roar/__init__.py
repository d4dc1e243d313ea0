"""Tests of the ROAR spec language front end (a package, so module names cannot clash with other test folders)."""

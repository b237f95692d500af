"""Synthetic bench logs with known physics: a virtual valve that differs from its CFD the way a
real one does, hidden effects from the library and beyond it, and the stress suites built from
them."""

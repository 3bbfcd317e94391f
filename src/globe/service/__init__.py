"""The assistance loop: an online assistant per household, its SQLite store, the HTTP service,
the Python client a robot imports, and a simulated robot."""

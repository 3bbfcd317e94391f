"""The assistance service: each household's session (:mod:`globe.session`) behind HTTP, its SQLite
store, the Python client a robot imports, and a simulated robot."""

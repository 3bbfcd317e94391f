"""Data layer: typed records, the CSV observation-log format, locating and importing data."""

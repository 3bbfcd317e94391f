"""Preprocessing: raw days -> activity sequences, movement events, activity runs."""

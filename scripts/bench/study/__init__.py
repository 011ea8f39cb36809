"""Modules of scripts/bench/study.py (the benchmark and stability study)."""

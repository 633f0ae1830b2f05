"""Experiments that reproduce and beat the source papers: fusion table, headway, guard, latency, ranging."""

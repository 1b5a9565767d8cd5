"""Ingest: every sensor's Features in bounded per-sensor buffers, and their blobs aligned to the fusion instant."""

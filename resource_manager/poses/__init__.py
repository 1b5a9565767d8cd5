"""Poses: where every camera is, surveyed or by mutual calibration (Eq. 3)."""

"""View planning for mobile cameras (Eqs. 4-6, Fig. 4)."""

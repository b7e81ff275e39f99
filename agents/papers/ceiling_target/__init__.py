"""The ceiling-target paper (Fukaya et al.): colour thresholds learned from images (``fit``)."""

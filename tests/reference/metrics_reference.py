#!/usr/bin/env python3
"""Reference PSNR/SSIM values for tests/test_metrics.cpp, from scikit-image (Debian
python3-skimage 0.19.3). The image pairs are defined by formulas, identical in the C++ test:
  a[y, x, c] = 0.5 + 0.4 sin(0.37 x + 0.11 c) cos(0.23 y - 0.05 c)
  b1 = clip(a + 0.08 sin(1.3 x + 2.1 y + c) cos(0.7 x y), 0, 1)      (structured noise)
  b2 = 0.8 a + 0.1                                                   (contrast change)
computed in double and stored as float32, width 32, height 24, 3 channels.
Run: python3 tests/reference/metrics_reference.py
"""
import numpy as np
from skimage.metrics import structural_similarity, peak_signal_noise_ratio

W, H = 32, 24
y, x, c = np.meshgrid(np.arange(H), np.arange(W), np.arange(3), indexing="ij")
a = (0.5 + 0.4 * np.sin(0.37 * x + 0.11 * c) * np.cos(0.23 * y - 0.05 * c)).astype(np.float32)
b1 = np.clip(a.astype(np.float64) + 0.08 * np.sin(1.3 * x + 2.1 * y + c) * np.cos(0.7 * x * y),
             0, 1).astype(np.float32)
b2 = (0.8 * a.astype(np.float64) + 0.1).astype(np.float32)
for name, b in (("noise", b1), ("contrast", b2)):
    s = structural_similarity(a.astype(np.float64), b.astype(np.float64), gaussian_weights=True,
                              sigma=1.5, use_sample_covariance=False, data_range=1.0,
                              channel_axis=2)
    p = peak_signal_noise_ratio(a.astype(np.float64), b.astype(np.float64), data_range=1.0)
    print(f"{name}: ssim {s:.12f} psnr {p:.12f}")

# Benchmark input for BENCHMARKS.md ("streaming I/O"): python3 benches/make_big_png.py W H OUT.png
# (needs numpy and opencv-python).
# Writes a W×H 16-bit normal-map PNG of a smooth analytic relief (sines + bumps) with cv2.
import sys, numpy as np, cv2
W, H, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
img = np.empty((H, W, 3), np.uint16)
xs = np.arange(W, dtype=np.float32)
for y0 in range(0, H, 1024):
    y = np.arange(y0, min(H, y0 + 1024), dtype=np.float32)[:, None]
    x = xs[None, :]
    # z = 6 sin(x/37) cos(y/53) + 3 sin((x+y)/11): gradients analytic
    p = 6/37*np.cos(x/37)*np.cos(y/53) + 3/11*np.cos((x+y)/11)
    q = -6/53*np.sin(x/37)*np.sin(y/53) + 3/11*np.cos((x+y)/11)
    n = np.sqrt(1 + p*p + q*q)
    nx, ny, nz = -p/n, -q/n, 1/n
    enc = lambda v: np.clip(np.round((v + 1) * 0.5 * 65535), 0, 65535).astype(np.uint16)
    # cv2 writes BGR
    img[y0:y0+y.shape[0], :, 0] = enc(nz)
    img[y0:y0+y.shape[0], :, 1] = enc(ny)
    img[y0:y0+y.shape[0], :, 2] = enc(nx)
cv2.imwrite(out, img, [cv2.IMWRITE_PNG_COMPRESSION, 1])

"""One predict + update of FilterPy's KalmanFilter on the same matrices as
the Rust and C++ benchmarks, for the comparison in bench/README.md.
FilterPy's update uses the Joseph form and an explicit inverse of S."""
import sys
import timeit

import numpy as np
from filterpy.kalman import KalmanFilter


def problem(n, m):
    phi = np.array([[1.0 if i == j else 0.01 * (((i * 7 + j * 3) % 11) - 5.0) / 5.0 for j in range(n)] for i in range(n)])
    q = np.diag([1e-4 * (1.0 + i) for i in range(n)])
    h = np.array([[1.0 if i == j else (0.1 if j == i + m else 0.0) for j in range(n)] for i in range(m)])
    r = np.array([[0.5 + 0.1 * i if i == j else 0.01 for j in range(m)] for i in range(m)])
    a = np.array([[(((i * 5 + j * 13) % 17) - 8.0) / 8.0 for j in range(n)] for i in range(n)])
    p0 = a @ a.T / n + np.eye(n)
    z = np.array([0.1 * i for i in range(m)])
    return phi, q, h, r, p0, z


def main():
    for n, m in [(15, 6), (21, 6)]:
        phi, q, h, r, p0, z = problem(n, m)
        kf = KalmanFilter(dim_x=n, dim_z=m)
        kf.F, kf.Q, kf.H, kf.R, kf.P = phi, q, h, r, p0
        kf.x = np.zeros((n, 1))

        def step():
            kf.predict()
            kf.update(z)

        number = 5000
        times = timeit.repeat(step, number=number, repeat=7)
        per = sorted(t / number * 1e9 for t in times)
        print(f"filterpy {n}x{m}: median {per[3]:.0f} ns per predict+update (min {per[0]:.0f})")
    print(f"numpy {np.__version__}, python {sys.version.split()[0]}")


if __name__ == "__main__":
    main()

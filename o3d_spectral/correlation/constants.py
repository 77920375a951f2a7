"""Numeric constants of the batched correlation, by the module using them."""

# -- correlation.backend: the batches of the batched correlation ---------------------------
# Calibrated on: 72x90x90 and 32x36x36 grids of the dragon scans on this machine's cores
# Measured again by: python eval/bench_correlation.py --suites SUITES --out RUN
# Trades: larger batches save per-call overhead on small grids, until they spill out of a
#   core's cache

#: Bytes of FFT grids (single precision, real) in one batch on the CPU: about a core's
#: second-level cache. Past it a batch is slower per rotation (72x90x90 grids: 3.5 ms in
#: batches of one, 6.7 ms in batches of 128); below it, batching saves the per-call
#: overhead of small grids (32x36x36: 6 a batch).
BATCH_BYTES = 2**20
#: Share of a GPU's free memory one batch may take, and the bytes it takes a cell of the
#: FFT grid: the moving grids (4), their half spectra (4), the whitened cross-power and
#: its intermediates (3 x 4) and the correlations (4), with CuPy's FFT work area; the
#: rest stays free for the plans and the other shape's batches.
GPU_MEMORY_SHARE, GPU_BYTES_PER_CELL = 0.25, 32
#: Workspaces a thread keeps (:class:`CompiledBackend`): one search correlates on two
#: grids, its batches of two sizes each (the last batch is shorter).
WORKSPACES = 8

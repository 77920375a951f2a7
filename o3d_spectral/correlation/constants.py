"""Numeric constants of the batched correlation, by the module using them."""

# -- correlation.backend: the batches of the batched correlation ---------------------------
# Calibrated on: the dense search's grids of a turntable pair, a dragon pair and a YCB-Video
#   crop (27x30x36 to 72x90x90) on this machine's cores
# Measured again by: python eval/bench_correlation.py --suites SUITES --out RUN
# Trades: a batch's arrays stay in a core's cache, until they spill out of it

#: Bytes of FFT grids (single precision, real) in one batch on the CPU: with its spectra
#: and correlations, about a core's second-level cache. From a quarter of it to the whole
#: the time a rotation takes is the same to 5% on one worker and on two (27x30x36 grids:
#: 0.18 ms in batches of 2, 4 or 8); past it a batch is slower (0.21 ms in batches of 35).
BATCH_BYTES = 2**20

# -- correlation.numpy_api: the batches on a GPU -------------------------------------------
# Calibrated on: the bytes CuPy's pipeline holds per cell of the FFT grid, counted array by
#   array (no GPU lent to measure them)
# Measured again by: python eval/device_check.py run --out OUT (on a machine with a GPU)
# Trades: larger batches, fewer launches, until the device runs out of memory (then the
#   batch is halved)

#: Share of a GPU's free memory one batch may take, and the bytes it takes a cell of the
#: FFT grid: the moving grids (4), their half spectra (4), the whitened cross-power and
#: its intermediates (3 x 4) and the correlations (4), with CuPy's FFT work area; the
#: rest stays free for the plans and the other shape's batches.
GPU_MEMORY_SHARE, GPU_BYTES_PER_CELL = 0.25, 32

# -- correlation.batched: the runs the batches are shared out in ---------------------------
# Calibrated on: the dense search's coarse grids of a turntable pair and a dragon pair
# Measured again by: python eval/bench_correlation.py --suites SUITES --out RUN
# Trades: more runs balance the workers when one core is slowed by other work; each run is
#   one call from Python, which holds the GIL for it

#: Runs of batches each worker gets (a run: one call of the compiled pipeline, the GIL
#: released for all of it); the batches' results do not depend on the runs.
RUNS_PER_WORKER = 4

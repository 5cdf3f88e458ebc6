"""Running the trials of a chain: seeds, chunks, workers, Dask, resume.

* Run ``i`` of ``N`` draws from ``numpy.random.SeedSequence(seed).spawn(N)[i]``
  (the children do not depend on N: run i has the same numbers for any
  number of runs), so a result never depends on how the runs are
  distributed.
* Runs are grouped in chunks of ``chunk`` runs; a finished chunk is written
  at once, atomically, as ``samples/chunk-NNNNN.csv`` (17 significant
  digits: the numbers read back bit for bit), its first line naming the
  digest of the manifest it was computed under. A new start skips the chunks
  already written only if ``samples/manifest.json`` is identical: the same
  content of every input file, the same settings, the same program
  (:mod:`photogram.montecarlo.manifest`); otherwise, and always with
  ``force``, every run is computed again, with one line saying why. An
  interrupted simulation loses nothing it had finished, and never mixes
  runs of different inputs.
* Engines: in this process (one worker), local processes (joblib, loky
  backend) or a Dask distributed cluster (``scheduler="tcp://HOST:PORT"``;
  the optional extra ``photogram[cluster]``). Every trial runs with one BLAS
  thread: the parallelism is across runs.
* A progress bar (tqdm) on a terminal; none when stderr is not a TTY.
"""

from __future__ import annotations

import io
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np

from photogram.errors import GeometryError, InputError
from photogram.montecarlo.manifest import fingerprint, manifest_digest, why_different
from photogram.project.atomic import atomic_write_text

__all__ = ["run_chunk", "Runner", "seeds_for", "chunk_ranges"]

log = logging.getLogger("photogram")


def seeds_for(seed: int, runs: int):
    """The SeedSequence of every run."""
    return np.random.SeedSequence(int(seed)).spawn(int(runs))


def chunk_ranges(runs: int, chunk: int):
    """(index, start, stop) of every chunk."""
    return [(k, s, min(s + chunk, runs)) for k, s in enumerate(range(0, runs, chunk))]


def run_chunk(chain, index, seeds):
    """Run the trials of one chunk: ``(index, values (n, n_out), failed (n,),
    CPU seconds)``."""
    from threadpoolctl import threadpool_limits
    n_out = len(chain.outputs.names)
    values = np.full((len(seeds), n_out), np.nan)
    failed = np.zeros(len(seeds), dtype=bool)
    cpu = time.process_time()
    with threadpool_limits(1):
        for j, s in enumerate(seeds):
            try:
                values[j] = chain.trial(s)
            except (GeometryError, np.linalg.LinAlgError, FloatingPointError):
                failed[j] = True
    return index, values, failed, time.process_time() - cpu


class Runner:
    """Run (or resume) the trials of a chain into ``folder/samples``.

    Parameters
    ----------
    chain : Chain
    folder : Path
        Output folder (created).
    runs, seed, chunk, workers : int
    scheduler : str or None
        Dask scheduler address; None: local.
    progress : bool
        Show a progress bar (only when stderr is a terminal).
    on_chunk : callable, optional
        Called as ``on_chunk(index)`` after a chunk is written (a hook for
        tests and front ends).
    force : bool
        Compute every run again, even if the samples folder holds finished
        chunks of the same inputs and settings.
    """

    def __init__(self, chain, folder, *, runs, seed, chunk=50, workers=1, scheduler=None,
                 progress=True, on_chunk=None, force=False):
        self.chain, self.folder = chain, Path(folder)
        self.runs, self.seed, self.chunk = int(runs), int(seed), int(chunk)
        self.workers, self.scheduler = int(workers), scheduler
        self.progress, self.on_chunk, self.force = progress, on_chunk, bool(force)
        self.samples = self.folder / "samples"
        self.ranges = chunk_ranges(self.runs, self.chunk)
        self.names = ["run"] + list(chain.outputs.names)

    # ---------------------------------------------------------------- files
    def chunk_path(self, index):
        return self.samples / f"chunk-{index:05d}.csv"

    def _prepare(self):
        """Write the manifest of this run; discard finished chunks unless it
        equals the one they were computed under (or with ``force``)."""
        self.samples.mkdir(parents=True, exist_ok=True)
        manifest = self.samples / "manifest.json"
        fp = fingerprint(self.chain, seed=self.seed, chunk=self.chunk)
        self.digest = manifest_digest(fp)
        finished = sorted(self.samples.glob("chunk-*.csv"))
        old = None
        if manifest.is_file():
            try:
                old = json.loads(manifest.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                old = None
        reason = "--force" if self.force else why_different(old, fp)
        if reason is not None and finished:
            log.warning("montecarlo: computing all %d runs again (%s); discarding %d finished "
                        "chunk(s) in %s", self.runs, reason, len(finished), self.samples)
            for f in finished:
                f.unlink()
        atomic_write_text(manifest, json.dumps(fp, indent=1) + "\n")

    def _read_chunk(self, index, start, stop):
        """The chunk's (values, failed), or None if missing, damaged or of
        other runs."""
        path = self.chunk_path(index)
        if not path.is_file():
            return None
        try:
            with open(path, encoding="utf-8") as f:
                if f.readline().strip() != f"# manifest {self.digest}":
                    return None           # computed under other inputs or settings
                header = f.readline().strip().split(",")
                data = np.loadtxt(f, delimiter=",", ndmin=2)
        except (OSError, ValueError):
            return None
        if header != self.names + ["failed"] or data.shape != (stop - start, len(header)) \
                or not np.array_equal(data[:, 0], np.arange(start, stop)):
            return None
        return data[:, 1:-1], data[:, -1].astype(bool)

    def _write_chunk(self, index, start, values, failed):
        factor = self.chain.outputs.factor
        data = np.column_stack([np.arange(start, start + len(values)), values * factor,
                                failed.astype(int)])
        buf = io.StringIO()
        buf.write(f"# manifest {self.digest}\n")
        buf.write(",".join(self.names + ["failed"]) + "\n")
        np.savetxt(buf, data, delimiter=",", fmt="%.17g")
        atomic_write_text(self.chunk_path(index), buf.getvalue())

    # ----------------------------------------------------------------- run
    def run(self):
        """Run what is missing; return ``(samples (runs, n_out) in reported
        units, failed (runs,), info)``."""
        t0 = time.perf_counter()
        self._prepare()
        todo = [r for r in self.ranges if self._read_chunk(*r) is None]
        done_runs = self.runs - sum(stop - start for _, start, stop in todo)
        if done_runs:
            log.info("montecarlo: resuming, %d of %d runs already done with the same inputs "
                     "and settings", done_runs, self.runs)
        seeds = seeds_for(self.seed, self.runs)
        jobs = [(k, start, seeds[start:stop]) for k, start, stop in todo]
        starts = {k: start for k, start, _ in todo}
        bar = _progress_bar(self.runs, done_runs, self.progress)
        cpu = 0.0
        try:
            for k, values, failed, seconds in self._execute(jobs):
                cpu += seconds
                self._write_chunk(k, starts[k], values, failed)
                if bar is not None:
                    bar.update(len(values))
                if self.on_chunk is not None:
                    self.on_chunk(k)
        finally:
            if bar is not None:
                bar.close()
        elapsed = time.perf_counter() - t0
        parts = [self._read_chunk(*r) for r in self.ranges]
        if any(p is None for p in parts):
            raise InputError("montecarlo: a chunk file is missing or damaged", file=self.samples,
                             hint="run the command again: it recomputes what is missing")
        values = np.vstack([p[0] for p in parts])
        failed = np.concatenate([p[1] for p in parts])
        n_new = self.runs - done_runs
        info = {"engine": self.engine, "workers": self.workers, "chunk": self.chunk,
                "runs_computed": n_new, "runs_resumed": done_runs, "seconds": elapsed,
                "runs_per_second": n_new / elapsed if n_new and elapsed > 0 else None,
                "cpu_seconds": cpu,
                "cpu_ms_per_run": 1e3 * cpu / n_new if n_new else None}
        return values, failed, info

    @property
    def engine(self):
        if self.scheduler:
            return "dask"
        return "local processes (joblib/loky)" if self.workers > 1 else "this process"

    def _execute(self, jobs):
        chain = self.chain
        if not jobs:
            return
        if self.scheduler:
            yield from _dask(chain, jobs, self.scheduler)
        elif self.workers > 1 and len(jobs) > 1:
            from joblib import Parallel, delayed
            par = Parallel(n_jobs=self.workers, backend="loky", return_as="generator_unordered")
            yield from par(delayed(run_chunk)(chain, k, s) for k, _, s in jobs)
        else:
            for k, _, s in jobs:
                yield run_chunk(chain, k, s)


def _dask(chain, jobs, address):
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise InputError("--scheduler needs the Python package 'distributed' (Dask)",
                         hint="pip install 'photogram[cluster]'") from None
    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError) as exc:
        raise InputError(f"cannot reach the Dask scheduler at {address}: {exc}",
                         hint="start it (dask scheduler) or run without --scheduler") from None
    try:
        remote = client.scatter(chain, broadcast=True)
        futures = [client.submit(run_chunk, remote, k, s, pure=False) for k, _, s in jobs]
        try:
            for fut in as_completed(futures):
                yield fut.result()
        except BaseException:
            client.cancel(futures)
            raise
    finally:
        client.close()


def _progress_bar(total, initial, wanted):
    if not wanted or not sys.stderr.isatty():
        return None
    try:
        from tqdm import tqdm
    except ImportError:          # pragma: no cover - tqdm is a dependency
        return None
    return tqdm(total=total, initial=initial, unit="run", desc="montecarlo", file=sys.stderr)

"""The CMA-ES plan: the ``cmaes`` package (the library Optuna's CmaEsSampler wraps) driven ask/tell directly,
generation after generation, with IPOP or BIPOP restarts (Auger & Hansen 2005; Hansen 2009) and CMA-ES with
margin (Hamano et al. 2022, ``cmaes.CMAwM``) when a dimension is categorical.

Search coordinates are the study's dimensions scaled to [0, 1] (a categorical one of n choices: steps of
1/(n-1), the choice's index); objectives are maximised or minimised as the study's ``search_plan`` says, and a
design whose objective is not finite ranks below every finite one. A generation's designs are spread over the
workers; its rows are buffered and stored as one part once ``batch`` trials have accumulated (parts are the unit
of durability, generations the unit of evaluation). The store is the record: resuming replays the stored parts'
designs and values through a fresh optimiser with the same seeds (checking that it asks the stored designs), so
an interrupted search continues to the same trials as an uninterrupted one, wherever the kill fell.
"""
from __future__ import annotations

import math

import numpy as np

from surgopt.parts import concat_rows
from surgopt.plans import BatchCollector, Designs, OptimiserPlan, Task, split

#: Initial step size in the [0, 1] search coordinates (a third of each range).
SIGMA0 = 0.3
#: The value told for a design whose objective is not finite (worse than any finite value when minimising).
NOT_FINITE = 1e300
#: A run restarts when ``cmaes`` says it should stop (tolerances of 1e-12, rarely met on a design problem) or when
#: its generations' best values have stalled: over the last ``10 + ceil(30 n / popsize)`` generations (Hansen's
#: "tolstagnation" window, shortened) they span less than STALL_RELATIVE of their magnitude.
STALL_RELATIVE = 1e-6


#: The cmaes package's ask and tell per trial on one core (benchmarks/bench_search.py: ~0.06-0.09 ms).
SECONDS_PER_TRIAL = 0.0001


class CmaesPlan(OptimiserPlan):
    name = "cmaes"
    seconds_per_trial = SECONDS_PER_TRIAL

    def record(self) -> dict:
        return {"name": self.name, "restarts": self.spec.restarts}

    # n_parts: every part but the last holds at least `batch` trials, so ceil(trials / batch) is an upper bound;
    # the session sets the exact count when the search ends (final_meta)

    def session(self, study, cfg, chunk: int, run, workers: int) -> CmaesSession:
        return CmaesSession(study.search_plan(cfg), run, workers)


class Space:
    """The study's dimensions <-> [0, 1] search coordinates."""

    def __init__(self, space: dict):
        self.names = list(space)
        self.doms = [space[n] for n in self.names]
        self.steps = np.array([0.0 if isinstance(d, tuple) else (1.0 / (len(d) - 1) if len(d) > 1 else 0.0)
                               for d in self.doms])
        self.categorical = any(not isinstance(d, tuple) for d in self.doms)

    def decode(self, u: np.ndarray) -> np.ndarray:
        """Search coordinates (rows) -> designs in the study's units (a categorical: its choice)."""
        out = np.empty_like(u, dtype=np.float64)
        for j, d in enumerate(self.doms):
            if isinstance(d, tuple):
                out[:, j] = d[0] + np.clip(u[:, j], 0.0, 1.0) * (d[1] - d[0])
            else:
                k = np.rint(np.clip(u[:, j], 0.0, 1.0) * (len(d) - 1)).astype(int)
                out[:, j] = np.asarray(d, dtype=np.float64)[k]
        return out


#: What ``ask_generation`` reads of a ``cmaes.CMA`` (its sampling state, version 0.10 to 0.13).
CMA_SAMPLING_STATE = ("_rng", "_mean", "_sigma", "_bounds", "_n_dim", "_n_max_resampling", "_eigen_decomposition")


def ask_generation(opt, n: int) -> np.ndarray | None:
    """n asks of a ``cmaes.CMA`` at once, bit for bit the points its ``ask`` would return one by one, leaving its
    random state where they would (tests/test_plans.py holds the two equal); None for any other optimiser
    (``CMAwM``'s margin, or a ``cmaes`` whose sampling state has other names), which is then asked point by point.

    ``CMA.ask`` draws z ~ N(0, I) (``RandomState.randn``), maps it to x = m + sigma B D z and keeps it when it lies
    in the bounds, up to ``n_max_resampling`` draws a point, then clips one more. Here the normals come in blocks
    of as many rows as points are still wanted (the same stream: ``randn(k, d)`` is k calls of ``randn(d)``, and
    no block draws a row the one-by-one asks would not), each row mapped by the same ``B D`` product, and the
    bounds are checked on the whole block: a per-point Python cost of ~5 us against ``ask``'s ~20 us a draw
    (~3 draws a trial on Table II, whose optimum lies on three bounds)."""
    import cmaes

    if type(opt) is not cmaes.CMA or not all(hasattr(opt, a) for a in CMA_SAMPLING_STATE):
        return None
    b, d = opt._eigen_decomposition()
    bd = b.dot(np.diag(d))
    mean, sigma, bounds, limit = opt._mean, opt._sigma, opt._bounds, opt._n_max_resampling
    out = np.empty((n, opt._n_dim))
    got, tries = 0, 0
    while got < n:
        z = opt._rng.randn(n - got, opt._n_dim)
        x = np.array([mean + sigma * bd.dot(row) for row in z])
        inside = np.ones(len(x), bool) if bounds is None else np.all((x >= bounds[:, 0]) & (x <= bounds[:, 1]),
                                                                     axis=1)
        for r in range(len(x)):
            if tries == limit:  # the draw after n_max_resampling misses: clipped into the bounds
                out[got] = np.where(x[r] > bounds[:, 1], bounds[:, 1], np.where(x[r] < bounds[:, 0], bounds[:, 0],
                                                                               x[r]))
            elif inside[r]:
                out[got] = x[r]
            else:
                tries += 1
                continue
            got, tries = got + 1, 0
    return out


class CmaesSession:
    unit = "trials"

    def __init__(self, plan, run, workers: int):
        self.plan, self.spec, self.run, self.workers = plan, plan.spec, run, workers
        self.space = Space(plan.space)
        (self.objective, direction), = plan.objectives[:1]
        self.sign = -1.0 if direction == "maximize" else 1.0  # cmaes minimises
        self.total = self.spec.trials
        self.restart = 0
        self.budget = {"large": 0, "small": 0}  # BIPOP: trials spent in each regime
        self.large_restarts = 0
        self.regime = "large"
        self.history: list[float] = []  # each generation's best told value since the last restart
        self.opt = self._optimizer(np.full(len(self.space.names), 0.5), SIGMA0, self.spec.population)  # the centre
        self.pop0 = self.opt.population_size
        self.evaluated = 0
        self.part = 0
        self.buffer: list[dict] = []
        self._gen = None
        self._replay()
        self.done = self.evaluated

    # -- the optimiser and its restarts ---------------------------------------------------------------

    def _rng(self, restart: int):
        return np.random.default_rng([self.spec.seed, restart])

    def _optimizer(self, mean, sigma, popsize):
        import cmaes

        seed = (self.spec.seed * 1_000_003 + self.restart) % (2 ** 31)
        bounds = np.tile([0.0, 1.0], (len(mean), 1))
        if self.space.categorical:
            return cmaes.CMAwM(mean=mean, sigma=sigma, bounds=bounds, steps=self.space.steps, seed=seed,
                               population_size=popsize)
        return cmaes.CMA(mean=mean, sigma=sigma, bounds=bounds, seed=seed, population_size=popsize)

    def _stalled(self) -> bool:
        window = 10 + math.ceil(30 * len(self.space.names) / self.opt.population_size)
        if len(self.history) < window:
            return False
        recent = self.history[-window:]
        return max(recent) - min(recent) <= STALL_RELATIVE * max(1.0, abs(min(recent)))

    def _restart(self) -> None:
        """IPOP: twice the population from a random mean. BIPOP (Hansen 2009): alternate that regime with a small
        one (population and step size drawn at random) so that each spends about the same number of trials."""
        self.restart += 1
        self.history = []
        rng = self._rng(self.restart)
        mean = rng.uniform(size=len(self.space.names))
        if self.spec.restarts == "bipop" and self.budget["small"] < self.budget["large"]:
            self.regime = "small"
            u = rng.uniform()
            large = self.pop0 * 2 ** self.large_restarts
            pop = max(self.pop0, math.floor(self.pop0 * (0.5 * large / self.pop0) ** (u ** 2)))
            self.opt = self._optimizer(mean, SIGMA0 * 10 ** (-2 * rng.uniform()), pop)
            return
        self.regime = "large"
        self.large_restarts += 1
        self.opt = self._optimizer(mean, SIGMA0, self.pop0 * 2 ** self.large_restarts)

    # -- generations ------------------------------------------------------------------------------------

    def _ask(self):
        """The next generation: (search coordinates to tell, designs to evaluate, whether it is whole)."""
        n = min(self.opt.population_size, self.total - self.evaluated)
        batch = ask_generation(self.opt, n)
        if batch is not None:  # cmaes.CMA: its n asks at once
            return list(batch), self.space.decode(batch), n == self.opt.population_size
        tell, ev = [], []
        for _ in range(n):
            x = self.opt.ask()
            if isinstance(x, tuple):  # CMAwM: (x for evaluation, x for tell)
                ev.append(x[0])
                tell.append(x[1])
            else:
                ev.append(x)
                tell.append(x)
        return tell, self.space.decode(np.asarray(ev)), n == self.opt.population_size

    def _tell(self, tell, values, whole: bool) -> None:
        self.evaluated += len(values)
        self.budget[self.regime] += len(values)
        if not whole:
            return  # the last, cut-short generation: the search ends here
        v = np.where(np.isfinite(values), self.sign * np.asarray(values, dtype=np.float64), NOT_FINITE)
        self.opt.tell(list(zip(tell, v)))
        self.history.append(float(v.min()))
        if self.spec.restarts != "none" and (self.opt.should_stop() or self._stalled()):
            self._restart()

    def _replay(self) -> None:
        """Bring the optimiser to where the stored parts (a prefix 0..m-1) leave it, telling their values."""
        from surgopt.errors import StoreError
        stored = self.run.done_tasks()
        m = 0
        while m in stored:
            m += 1
        if m == 0:
            return
        cols = concat_rows([{c: v.to_numpy() for c, v in zip(t.column_names, t.columns)}
                            for t in (self.run.part_table(k) for k in range(m))])
        x_all = np.column_stack([np.asarray(cols[n], dtype=np.float64) for n in self.space.names])
        v_all = np.asarray(cols[self.objective], dtype=np.float64)
        i = 0
        while i < len(v_all):
            tell, x, whole = self._ask()
            stored_x = x_all[i:i + len(x)]
            if stored_x.shape != x.shape or not np.allclose(stored_x, x, rtol=0, atol=1e-12):
                raise StoreError(f"{self.run.path}: the stored trials {i}-{i + len(x) - 1} are not the ones this "
                                 f"search asks (another version's search?); rerun with --force to search again")
            self._tell(tell, v_all[i:i + len(x)], whole)
            i += len(x)
        self.part = m
        for k in sorted(stored):
            if k >= m:  # after a gap: recomputed the same way
                self.run.manifest["parts"].pop(str(k), None)

    @property
    def remaining(self) -> bool:
        return self.evaluated < self.total

    def next_tasks(self) -> list[Task]:
        if self.evaluated >= self.total:
            return []
        tell, x, whole = self._ask()
        ids = self.evaluated + np.arange(len(x))
        slices = split(x, ids, self.workers)
        self._gen = (tell, whole, BatchCollector(len(slices)))
        return [Task(self.part, j, Designs(xs, i, "cmaes")) for j, (xs, i) in enumerate(slices)]

    def on_result(self, task: Task, cols: dict) -> list[tuple[int, dict]]:
        tell, whole, collector = self._gen
        cols = collector.add(task.sub, cols)
        if cols is None:
            return []
        self._tell(tell, np.asarray(cols[self.objective], dtype=np.float64), whole)
        self.done = self.evaluated
        self.buffer.append(cols)
        held = sum(len(b[self.objective]) for b in self.buffer)
        if held < self.spec.trials_per_part and self.evaluated < self.total:
            return []
        part, self.part, rows, self.buffer = self.part, self.part + 1, concat_rows(self.buffer), []
        return [(part, rows)]

    def final_meta(self) -> dict:
        return {"n_tasks": self.part, "search_restarts": self.restart}

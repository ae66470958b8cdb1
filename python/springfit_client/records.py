"""What springfitd sends, as read-only records (proto/RPC.md, proto/RUN.md).

Every record keeps the object the server sent in `raw` (also reachable as `record["key"]` and
`record.get("key")`), and reads the members it knows into attributes. Members it does not know
are ignored (a newer server may add some: proto/RPC.md, "Readers ignore members they do not
know"); members it knows but the server did not send (an older server) read as None.
"""

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, List, Optional

__all__ = [
    "USABLE", "UNMET_REQUEST", "UNUSABLE", "DOUBTFUL", "FINAL_STATES", "Outcome", "TraceRow", "Progress",
    "Job", "Result", "ServerInfo", "Submission", "Improvement",
]

# outcome.verdict (proto/RUN.md, "The verdict").
USABLE = "usable"                # a model, every request met
UNMET_REQUEST = "unmet_request"  # a usable model that misses a hard request (budget, target)
UNUSABLE = "unusable"            # a mechanism, no equilibrium, no better than the rest shape
DOUBTFUL = "doubtful"            # a usable model the certificate or the nonlinear judgement doubts

# The states a job ends in (proto/RPC.md, "Job").
FINAL_STATES = ("succeeded", "failed", "cancelled")


class _Record:
    """Mapping-style access to the object as sent, beside the typed attributes."""

    def __getitem__(self, key):
        return self.raw[key]

    def __contains__(self, key):
        return key in self.raw

    def get(self, key, default=None):
        return self.raw.get(key, default)

    def to_dict(self):
        """The object as the server sent it (a copy)."""
        return dict(self.raw)

    @classmethod
    def from_json(cls, obj):
        """Reads the members this class knows; ignores the others (kept in raw)."""
        if not isinstance(obj, dict):
            raise TypeError(f"{cls.__name__}: expected a JSON object, got {type(obj).__name__}")
        values = {}
        for f in dataclasses.fields(cls):
            if f.name == "raw":
                continue
            value = obj.get(f.name)
            reader = _NESTED.get((cls.__name__, f.name))
            values[f.name] = reader(value) if reader and isinstance(value, dict) else value
        return cls(raw=dict(obj), **values)


@dataclass(frozen=True)
class Outcome(_Record):
    """A finished job's verdict and headline numbers (proto/RUN.md, "The verdict")."""
    verdict: Optional[str] = None          # USABLE, UNMET_REQUEST, UNUSABLE or DOUBTFUL
    headline: Optional[str] = None         # the verdict line `springfit run` prints
    reason: Optional[str] = None           # unusable: why
    unmet: Optional[List[str]] = None      # unmet_request: each request not met
    doubts: Optional[List[str]] = None     # doubtful: each doubt (worse than the recipe where)
    springs: Optional[int] = None          # the model's springs
    unseen_springs: Optional[int] = None
    rms_error: Optional[float] = None      # E on the named load cases (None: no equilibrium)
    baseline_rms_error: Optional[float] = None
    # A linear response (rms_error is then the small-load limit's): E on the same cases as the
    # simulator runs the springs (nonlinear; "inf": no equilibrium), the model's and the
    # baseline's; None otherwise (proto/RUN.md, "The verdict").
    simulated_rms_error: Optional[float] = None
    baseline_simulated_rms_error: Optional[float] = None
    held_out: Optional[dict] = None
    raw: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def usable(self):
        """True for a model to use (usable, unmet_request or doubtful); False for unusable."""
        return self.verdict in (USABLE, UNMET_REQUEST, DOUBTFUL)


def _rms_of(normalized_error):
    """E, the square root of a normalised error (E squared); None where there is none."""
    e = normalized_error
    return math.sqrt(e) if isinstance(e, (int, float)) and e >= 0 else None


@dataclass(frozen=True)
class TraceRow(_Record):
    """One stored generation of a job's search (proto/RUN.md, "The trace")."""
    generation: Optional[int] = None
    wall_seconds: Optional[float] = None
    evaluations: Optional[int] = None
    cache_hits: Optional[int] = None
    best_cost: Optional[float] = None
    best_normalized_error: Optional[float] = None
    mean_cost: Optional[float] = None
    missing: Optional[int] = None          # None when the reference topology is unknown
    extra: Optional[int] = None
    raw: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def rms_error(self):
        """E of the best so far: the square root of best_normalized_error."""
        return _rms_of(self.best_normalized_error)


@dataclass(frozen=True)
class Progress(TraceRow):
    """A job.progress notification: a trace row with its job and generation limit. `final` is
    True for the last row of a finished job, which Client.watch reports once at the end. A
    continuous job's rows are its fit's steps (`generation` the step, `max_generations` 0)."""
    job_id: Optional[int] = None
    max_generations: Optional[int] = None
    final: bool = False

    @classmethod
    def from_json(cls, obj, final=False):
        p = super().from_json(obj)
        return dataclasses.replace(p, final=final)


@dataclass(frozen=True)
class Phase(_Record):
    """A job.phase notification: where a job's step has got between two rows (the analysis,
    a fit's steps, the sparsity path, the certificate), as `springfit watch` shows it."""
    job_id: Optional[int] = None
    phase: Optional[str] = None            # proto/RPC.md, job.phase: probe_fit, certificate, ...
    wall_seconds: Optional[float] = None   # on the run's clock
    generation: Optional[int] = None       # the generation in progress (path: its points)
    evaluations: Optional[int] = None      # fit: its accepted steps
    best_normalized_error: Optional[float] = None  # None: no model yet in this phase
    eta_seconds: Optional[float] = None    # the phase's seconds left at most (None: no estimate)
    max_generations: Optional[int] = None
    raw: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def rms_error(self):
        """E of the phase's latest model (None: none yet)."""
        return _rms_of(self.best_normalized_error)


@dataclass(frozen=True)
class Job(_Record):
    """A job as job.get, job.list, job.watch and job.finished show it (proto/RPC.md, "Job")."""
    job_id: Optional[int] = None
    label: Optional[str] = None
    priority: Optional[int] = None
    seed: Optional[int] = None
    idempotency_key: Optional[str] = None
    state: Optional[str] = None            # preparing, queued, running; FINAL_STATES
    error: Optional[str] = None            # why it failed
    scene: Optional[str] = None            # the scene's name
    genes: Optional[int] = None
    strategy: Optional[str] = None
    max_generations: Optional[int] = None
    created_at: Optional[float] = None
    started_at: Optional[float] = None
    finished_at: Optional[float] = None
    progress: Optional[TraceRow] = None    # the latest generation
    checkpoint_generation: Optional[int] = None
    exact: Optional[bool] = None
    outcome: Optional[Outcome] = None      # finished with a result: the verdict
    raw: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def finished(self):
        return self.state in FINAL_STATES

    @property
    def verdict(self):
        """USABLE, UNMET_REQUEST or UNUSABLE once finished with a result; None otherwise."""
        return self.outcome.verdict if self.outcome else None

    @property
    def rms_error(self):
        """E of the returned model once finished; of the best so far while it runs."""
        if self.outcome:
            return self.outcome.rms_error
        return self.progress.rms_error if self.progress else None


@dataclass(frozen=True)
class Result(_Record):
    """A job's result: the object `springfit run --json` prints (proto/RUN.md, "The result
    object") with job_id and state. Members not read here: result["baseline"], .raw."""
    job_id: Optional[int] = None
    state: Optional[str] = None
    scene: Optional[str] = None
    strategy: Optional[str] = None         # as asked
    ran: Optional[str] = None              # the strategy that ran
    identify: Optional[str] = None
    response: Optional[str] = None
    seed: Optional[int] = None
    stop: Optional[str] = None
    stop_message: Optional[str] = None
    outcome: Optional[Outcome] = None
    exact: Optional[bool] = None
    hamming: Optional[int] = None
    missing: Optional[list] = field(default=None, repr=False)
    extra: Optional[list] = field(default=None, repr=False)
    genes: Optional[int] = None
    springs: Optional[List[List[int]]] = field(default=None, repr=False)   # node pairs [i, j]
    stiffness: Optional[List[float]] = field(default=None, repr=False)  # per spring
    unidentifiable: Optional[list] = field(default=None, repr=False)
    cost: Optional[float] = None
    normalized_error: Optional[float] = None
    rms_error: Optional[float] = None      # E
    generations: Optional[int] = None
    best_generation: Optional[int] = None
    evaluations: Optional[int] = None
    wall_seconds: Optional[float] = None
    raw: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def verdict(self):
        return self.outcome.verdict if self.outcome else None


@dataclass(frozen=True)
class ServerInfo(_Record):
    """server.info (proto/RPC.md)."""
    name: Optional[str] = None
    version: Optional[str] = None
    protocol: Optional[int] = None
    auth_required: Optional[bool] = None
    daemon: Optional[str] = None
    store: Optional[str] = None
    workers: Optional[int] = None
    max_running: Optional[int] = None
    running: Optional[int] = None
    queued: Optional[int] = None           # None while the store does not answer
    store_error: Optional[str] = None
    strategies: Optional[List[str]] = None
    limits: Optional[dict] = None
    raw: dict = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True)
class Submission(_Record):
    """job.submit's answer: the job, and whether this call created it (False: a job with the
    same idempotency key existed)."""
    created: Optional[bool] = None
    job: Optional[Job] = None
    notices: Optional[List[str]] = None    # the scene's notices (a created job's)
    raw: dict = field(default_factory=dict, repr=False, compare=False)


@dataclass(frozen=True)
class Improvement(_Record):
    """An improvement of a job's best topology (proto/RPC.md, job.improvements)."""
    generation: Optional[int] = None
    wall_seconds: Optional[float] = None
    cost: Optional[float] = None
    normalized_error: Optional[float] = None
    missing: Optional[int] = None
    extra: Optional[int] = None
    genome: Optional[str] = None
    raw: dict = field(default_factory=dict, repr=False, compare=False)


# Members that are records themselves: (class, member) -> reader.
_NESTED: Any = {
    ("Job", "progress"): TraceRow.from_json,
    ("Job", "outcome"): Outcome.from_json,
    ("Result", "outcome"): Outcome.from_json,
    ("Submission", "job"): Job.from_json,
}

"""A native vector environment: every controlled pedestrian of K copies of ``crowd_v0`` as one batch.

:class:`CrowdVectorEnv` is a Gymnasium :class:`~gymnasium.vector.VectorEnv` of ``num_envs = K × A``
*slots* (K copies, A = ``len(possible_agents)`` agents each; slot ``c A + a`` is agent ``a`` of copy
``c``), for parameter sharing: one policy acts for all slots. Observations ``(K A, D)`` float32, actions
``(K A, 2)``, rewards, terminations and truncations ``(K A,)``, built in arrays: each step loops over the
K copies, never over agents (each copy advances through the same array core as the PettingZoo API,
:meth:`~crowd_env.envs.crowd_v0.CrowdParallelEnv._advance`, and one compiled call files its results
into the slots), in this process or in ``workers`` processes. ``stable_baselines3`` trains on it through
:class:`crowd_env.envs.sb3.CrowdSB3VecEnv`; TorchRL wraps it as a Gymnasium vector environment.

Agents that leave (black death, with a mask):
    On the step its agent leaves (terminated: it reached an exit; truncated: ``max_steps``), a slot
    reports ``terminated`` / ``truncated`` with the agent's last observation in ``infos["final_obs"]``
    (mask ``infos["_final_obs"]``) and its episode return and length in ``infos["episode_return"]``
    and ``infos["episode_length"]`` (mask ``infos["episode_ended"]``). Until its copy resets, the slot is *padding*:
    observation zeros, reward 0, neither terminated nor truncated, its action ignored (any value),
    ``infos["alive"]`` False. ``infos["acted"]`` marks the slots whose action was used this step, so
    an algorithm can mask padding out instead of learning on it.
Automatic reset per copy (Gymnasium's ``AutoresetMode.SAME_STEP``):
    when the last agent of a copy ends, the copy resets in the same step: its slots return the first
    observations of the new episode, and the padding slots end their padding episode with
    ``terminated`` True (final observation zeros, ``episode_ended`` False), so no return crosses the reset.
Infos:
    a flat dict of ``(K A, …)`` arrays with the same keys after :meth:`~CrowdVectorEnv.reset` and every
    step (``alive``, ``acted``, ``copy``, ``final_obs``, ``_final_obs``, ``episode_return``,
    ``episode_length``, ``episode_ended``, and ``reward_terms`` when the copies report their reward's terms:
    ``(K A, T)``, each slot's contribution of each term this step, columns in the order of
    :attr:`CrowdVectorEnv.reward_term_names`, zeros for padding and after a reset), so batch readers such as
    TorchRL's see fixed specs. A ``reward_fn`` without a ``names`` attribute has no terms known before its first
    step: its terms stay out of the vector infos.
Seeding per copy:
    ``reset(seed=s)`` resets copy c with seed ``s + c`` (or ``seed=[s_0, …, s_{K−1}]``); later automatic
    resets continue each copy's stream. Copy c then gives exactly the observations, rewards and
    trajectories of ``crowd_v0.parallel_env(**options)`` reset with the same seed and fed the same
    actions (``tests/envs/test_vector.py``).
Global state:
    :meth:`CrowdVectorEnv.state` is ``(K, S)`` (:meth:`~crowd_env.envs.crowd_v0.CrowdParallelEnv.state` of
    each copy); ``slot_copy[i]`` is the copy of slot i, so ``state()[slot_copy]`` is each slot's.
Worker processes (``workers=W``):
    ``vector_env(K, workers=W, ...)`` splits the K copies into W contiguous groups and steps them in W
    processes at once: group 0 in this process (which would otherwise wait), groups 1 … W−1 in worker
    processes (``start_method``: ``"spawn"`` by default, or ``"forkserver"``; ``"fork"`` too where the
    platform has it, unsafe with threads). Actions, observations, rewards, flags and the info
    arrays pass through one shared-memory buffer, so a step pickles nothing but a short command per
    worker; the results are bitwise those of ``workers=1`` with the same seeds
    (``tests/envs/test_vector.py``). The copies must pickle (module-level reward and background
    functions). An exception while stepping a group (group 0's too) is raised as
    :class:`~crowd_env.errors.WorkerError` with the traceback in its message (the original exception as
    its ``__cause__``); a worker that dies is a ``WorkerError`` too, never a hang (while starting as well);
    after either, the vector environment refuses further use. With ``"spawn"`` and ``"forkserver"`` each
    worker imports the main module (the user's script) again, so a script must make the vector environment
    under ``if __name__ == "__main__":``; one that does not fails at once with a ``WorkerError`` that says
    so. :meth:`CrowdVectorEnv.close` stops the workers. With workers, ``envs`` are unstepped templates
    (every group, group 0 included, steps copies of them): read or change the live copies through
    :meth:`~CrowdVectorEnv.call`, :meth:`~CrowdVectorEnv.get_attr`, :meth:`~CrowdVectorEnv.set_attr`,
    :meth:`~CrowdVectorEnv.state` and :meth:`~CrowdVectorEnv.render`.
"""
from __future__ import annotations

import multiprocessing
import traceback
from multiprocessing.connection import wait

import cloudpickle
import numba as nb
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from crowd_env.errors import ActionError, EnvOptionError, EnvStateError, WorkerError

from ..core.checks import check_integer, check_seed
from ..threads import limit_worker_threads
from .config import make_config, resolve_options
from .crowd_v0 import CrowdParallelEnv, actions_within, real_actions, term_rows

__all__ = ["CrowdVectorEnv", "vector_env", "gym_vector_env", "WorkerError"]

START_METHODS = ("spawn", "forkserver", "fork")
START_TIMEOUT_S = 600.0  # a live worker that has not unpickled its copies by then is an error
_CLOSE_TIMEOUT_S = 10.0
_GUARD_HINT = ("With start_method 'spawn' or 'forkserver' every worker process imports the main module (your "
               "script) again before it starts, so a script that makes a vector environment with workers > 1 at its "
               "top level runs again in each worker and fails there. Put that code under "
               "`if __name__ == \"__main__\":` (or in a function called from there); see the module docstring of "
               "crowd_env.envs.vector.")


def _importing_main() -> bool:
    """True in a worker process while it imports the parent's main module (multiprocessing's bootstrapping
    phase, in which no process may be started)."""
    return bool(getattr(multiprocessing.current_process(), "_inheriting", False))


def _spaces_key(env: CrowdParallelEnv) -> tuple:
    a = env.possible_agents[0]
    return (env.observation_space(a), env.action_space(a), len(env.possible_agents), env.dt_s, env.state_space,
            env.observation_frame)


def _check_workers(workers, copies: int) -> int:
    check_integer("workers", workers, error=EnvOptionError, minimum=1)
    if workers > copies:
        raise EnvOptionError(f"workers = {workers} exceeds the {copies} copies: each worker steps at least one "
                             f"copy; give workers <= {copies}")
    return int(workers)


# The arrays of a step, per slot: name -> (dtype, columns or None), for ``dim`` = (observation size, number
# of reward terms reported; 0: none). One buffer holds them all (shared with the workers); the serial path
# allocates them fresh each step.
def _fields(dim: tuple) -> dict:
    obs_dim, n_terms = dim
    fields = {"actions": (np.float64, 2), "obs": (np.float32, obs_dim), "rewards": (np.float64, None),
              "terminated": (np.bool_, None), "truncated": (np.bool_, None), "final_obs": (np.float32, obs_dim),
              "_final_obs": (np.bool_, None), "episode_return": (np.float64, None),
              "episode_length": (np.int64, None), "episode_ended": (np.bool_, None), "acted": (np.bool_, None),
              "alive": (np.bool_, None)}
    if n_terms:
        fields["reward_terms"] = (np.float64, n_terms)
    return fields


def _arrays(n: int, dim: tuple, buffer=None) -> dict:
    """The step arrays of ``n`` slots: zeros, or views into ``buffer`` (bytes laid out field by field)."""
    out, offset = {}, 0
    for name, (dtype, cols) in _fields(dim).items():
        shape = (n,) if cols is None else (n, cols)
        if buffer is None:
            out[name] = np.zeros(shape, dtype)
            continue
        size = int(np.prod(shape)) * np.dtype(dtype).itemsize
        out[name] = np.frombuffer(buffer, dtype=dtype, count=int(np.prod(shape)), offset=offset).reshape(shape)
        offset += -(-size // 8) * 8  # 8-byte aligned
    return out


_NO_TERMS = np.zeros((0, 0))  # no reward terms to file (_record)


def _buffer_size(n: int, dim: tuple) -> int:
    total = 0
    for dtype, cols in _fields(dim).values():
        total += -(-(n * (cols or 1) * np.dtype(dtype).itemsize) // 8) * 8
    return total


@nb.njit(cache=True)
def _record(slots, step, out, running, term_rows, slot_terms):
    """File one copy's ``step`` = ``(observations, rewards, terminated, truncated)`` (rows in its live agents'
    order) into the slot arrays ``out`` = ``(obs, rewards, terminated, truncated, final_obs, has_final,
    episode_return, episode_length, episode_ended)`` at ``slots``, with the episodes so far ``running`` = ``(return,
    length, alive)``: an agent that ended gets its last observation as the final one, its episode return and length,
    and turns into padding. ``term_rows`` (n, T): each agent's reward terms, copied to ``slot_terms`` (none when
    T = 0)."""
    o, r, te, tr = step
    obs, rewards, terminated, truncated, final_obs, has_final, ep_r, ep_l, has_ep = out
    ret, length, alive = running
    for a in range(slots.shape[0]):
        i = slots[a]
        for t in range(term_rows.shape[1]):
            slot_terms[i, t] = term_rows[a, t]
        rewards[i] = r[a]
        ret[i] += r[a]
        length[i] += 1
        terminated[i] = te[a]
        truncated[i] = tr[a]
        if te[a] or tr[a]:
            final_obs[i, :] = o[a, :]
            has_final[i] = True
            ep_r[i] = ret[i]
            ep_l[i] = length[i]
            has_ep[i] = True
            ret[i] = 0.0
            length[i] = 0
            alive[i] = False
        else:
            obs[i, :] = o[a, :]


class _Copies:
    """A group of copies stepped one after another in this process, writing into slot arrays: the work of
    the vector environment with ``workers=1``, and of each worker process otherwise."""

    def __init__(self, envs, alive: np.ndarray):
        self.envs = envs
        self.n_agents = len(envs[0].possible_agents)
        self.alive = alive  # (slots,) bool, this group's: possibly a view into the shared buffer
        self.ret = np.zeros(alive.shape[0])
        self.length = np.zeros(alive.shape[0], np.int64)
        # per copy: pedestrian index -> agent position (slot offset), -1 for background pedestrians
        self.position = []
        for e in envs:
            pos = np.full(e.n_pedestrians, -1, np.int64)
            pos[[e._index_of[a] for a in e.possible_agents]] = np.arange(self.n_agents)
            self.position.append(pos)
        self._kept_slots = [None] * len(envs)  # per copy: (its _agent_index array, their slots) (_slots)

    def _reset_copy(self, c: int, seed, options, obs) -> slice:
        env = self.envs[c]
        o, _ = env.reset(seed=seed, options=options)
        rows = slice(c * self.n_agents, (c + 1) * self.n_agents)
        self.alive[rows] = True
        obs[rows] = np.stack([o[a] for a in env.possible_agents])
        self.ret[rows], self.length[rows] = 0.0, 0
        return rows

    def reset(self, seeds, options, out: dict) -> None:
        """Reset every copy (copy c with ``seeds[c]``); writes ``out`` (zeros on entry)."""
        for c, s in enumerate(seeds):
            self._reset_copy(c, s, options, out["obs"])

    def step(self, actions: np.ndarray, out: dict) -> None:
        """One step of every copy with the slots' ``actions`` (validated); writes ``out`` (zeros on entry but
        for the actions and ``alive``)."""
        acted = out["acted"]
        acted[:] = self.alive
        A = self.n_agents
        obs = out["obs"]
        slot_terms = out.get("reward_terms", _NO_TERMS)
        slot_arrays = (obs, out["rewards"], out["terminated"], out["truncated"], out["final_obs"], out["_final_obs"],
                       out["episode_return"], out["episode_length"], out["episode_ended"])
        running = (self.ret, self.length, self.alive)
        for c, env in enumerate(self.envs):
            slots = self._slots(c, env)
            o, r, te, tr, info = env._advance(actions[slots])
            terms = info.get("reward_terms") if slot_terms is not _NO_TERMS else None
            _record(slots, (o, r, te, tr), slot_arrays, running, _NO_TERMS if terms is None else term_rows(terms),
                    slot_terms)
            if not env.agents:  # the copy's episode is over: reset it in this step
                base = c * A
                rows = slice(base, base + A)
                padding = np.arange(base, base + A)[~acted[rows]]
                out["terminated"][padding] = True
                out["_final_obs"][padding] = True  # final observation: zeros
                self._reset_copy(c, None, None, obs)

    def _slots(self, c: int, env) -> np.ndarray:
        """The slots of copy ``c``'s live agents, in ``env.agents`` order; kept while its agents stay the same
        (the environment replaces its ``_agent_index`` array when agents leave or at a reset)."""
        index = env._agent_index
        kept = self._kept_slots[c]
        if kept is None or kept[0] is not index:
            kept = self._kept_slots[c] = (index, c * self.n_agents + self.position[c][index])
        return kept[1]

    def state(self) -> np.ndarray:
        return np.stack([e.state() for e in self.envs])

    def call(self, copies, name: str, args, kwargs) -> list:
        out = []
        for c in copies:
            value = getattr(self.envs[c], name)
            out.append(value(*args, **kwargs) if callable(value) else value)
        return out

    def set_attr(self, copies, name: str, values) -> None:
        for c, v in zip(copies, values):
            setattr(self.envs[c], name, v)

    def close(self) -> None:
        for e in self.envs:
            e.close()


def _serve(copies: _Copies, out: dict, results: list, cmd: str, arg):
    """Run one command on a group of copies (in a worker process or, for group 0, in the parent); returns
    the reply."""
    if cmd in ("step", "reset"):
        for v in results:
            v[...] = 0
    if cmd == "step":
        copies.step(out["actions"], out)
        return None
    if cmd == "reset":
        copies.reset(arg[0], arg[1], out)
        return None
    if cmd == "state":
        return copies.state()
    if cmd == "call":
        return copies.call(*arg)
    if cmd == "set_attr":
        return copies.set_attr(*arg)
    raise EnvStateError(f"unknown worker command {cmd!r}")


def _group(envs, buffer, n_slots: int, dim: tuple, lo: int, hi: int):
    """A group's copies, its views of slots ``lo:hi`` of the shared buffer and the result arrays zeroed
    before each step."""
    views = _arrays(n_slots, dim, buffer)
    out = {k: v[lo:hi] for k, v in views.items()}
    return _Copies(envs, out["alive"]), out, [v for k, v in out.items() if k not in ("actions", "alive")]


def _worker(conn, buffer, n_slots: int, dim: tuple, lo: int, hi: int) -> None:
    """Body of a worker process: receives its copies through ``conn`` (cloudpickled, as the geometry's mapping
    proxies need; slots ``lo:hi``), answers ``("ready", None)`` (or ``("error", ...)``), then steps them on
    the parent's commands."""
    limit_worker_threads()  # the copies are spread over the processes: one BLAS thread each (crowd_env.threads)
    try:
        copies, out, results = _group(cloudpickle.loads(conn.recv_bytes()), buffer, n_slots, dim, lo, hi)
    except (EOFError, KeyboardInterrupt):  # the parent is gone
        return
    except Exception as exc:
        try:
            conn.send(("error", (traceback.format_exc(), exc)))
        except Exception:  # the exception itself does not pickle
            conn.send(("error", (traceback.format_exc(), None)))
        return
    conn.send(("ready", None))
    while True:
        try:
            cmd, arg = conn.recv()
        except (EOFError, KeyboardInterrupt):  # the parent is gone
            return
        try:
            if cmd == "close":
                copies.close()
                conn.send(("ok", None))
                return
            reply = _serve(copies, out, results, cmd, arg)
            conn.send(("ok", cloudpickle.dumps(reply) if cmd == "call" else reply))  # any object may come back
        except Exception as exc:  # report it with its traceback; the parent decides
            try:
                conn.send(("error", (traceback.format_exc(), exc)))
            except Exception:  # the exception itself does not pickle
                conn.send(("error", (traceback.format_exc(), None)))


class _Workers:
    """The processes of a vector environment and the shared buffer they write into: group 0 of the copies
    is stepped in this process (so that it works while the others do, instead of waiting), groups
    1 … W−1 in worker processes."""

    def __init__(self, envs, workers: int, start_method: str, n_slots: int, dim: tuple, n_agents: int):
        ctx = multiprocessing.get_context(start_method)
        self.n_slots, self.dim = n_slots, dim
        self.buffer = ctx.RawArray("b", _buffer_size(n_slots, dim))
        self.views = _arrays(n_slots, dim, self.buffer)
        self.groups = np.array_split(np.arange(len(envs)), workers)
        self.conns, self.procs = [None], [None]  # index w: worker w's pipe and process (none for group 0)
        self.broken = None
        if _importing_main():
            raise EnvOptionError(f"a vector environment with workers > 1 was made while a {start_method!r} worker "
                                 f"process was importing the main module: {_GUARD_HINT}")
        try:
            payloads = {}
            for w, g in enumerate(self.groups):
                lo, hi = int(g[0]) * n_agents, (int(g[-1]) + 1) * n_agents
                try:
                    group = cloudpickle.dumps([envs[c] for c in g])  # the live copies; envs stay templates
                    if w == 0:
                        self.local = _group(cloudpickle.loads(group), self.buffer, n_slots, dim, lo, hi)
                        continue
                    parent, child = ctx.Pipe()
                    try:
                        # The copies go through the pipe after the start, not as arguments: Process.start()
                        # writes its arguments into the child with the child's read end still open in this
                        # process, so a child that dies before reading them (a script without the
                        # ``__main__`` guard) would block start() for ever.
                        proc = ctx.Process(target=_worker, args=(child, self.buffer, n_slots, dim, lo, hi),
                                           daemon=True, name=f"crowd-vector-worker-{w}")
                        proc.start()
                    finally:
                        child.close()
                except Exception as exc:
                    raise EnvOptionError(f"could not start worker {w} for copies {g[0]}..{g[-1]} ({exc}); with "
                                         "workers > 1 the copies must pickle (module-level reward_fn and "
                                         "background_policy)") from exc
                self.conns.append(parent)
                self.procs.append(proc)
                payloads[w] = group
            for w, group in payloads.items():
                try:
                    self.conns[w].send_bytes(group)
                except (BrokenPipeError, ConnectionError, OSError):
                    pass  # it died: _await_start says how
            for w in payloads:
                self._await_start(w)
        except BaseException:
            self.close()
            raise

    def _await_start(self, w: int) -> None:
        """Wait for worker ``w``'s ``ready``; a worker that dies, raises or is silent for
        :data:`START_TIMEOUT_S` is a :class:`WorkerError` (never a hang)."""
        conn, proc = self.conns[w], self.procs[w]
        ready = wait([conn, proc.sentinel], timeout=START_TIMEOUT_S)
        if not ready:
            raise WorkerError(f"{self._where(w)} did not start within {START_TIMEOUT_S:g} s")
        try:
            if conn not in ready and not conn.poll():
                raise EOFError
            status, payload = conn.recv()
        except (EOFError, OSError):
            proc.join(_CLOSE_TIMEOUT_S)
            raise WorkerError(f"{self._where(w)} died while starting (exit code {proc.exitcode}; its own error is "
                              f"on its stderr, above). The usual cause: {_GUARD_HINT}") from None
        if status == "error":
            error = self._error(w, *payload)
            raise error

    def _where(self, w: int) -> str:
        g = self.groups[w]
        where = "this process" if w == 0 else f"pid {self.procs[w].pid}"
        return f"worker {w} ({where}, copies {g[0]}..{g[-1]})"

    def run(self, messages: dict) -> dict:
        """Send ``messages`` (worker -> (command, argument)), run group 0's here meanwhile, and return the
        replies (worker -> reply). An exception or a dead worker raises :class:`WorkerError` (after every
        reply is in, so the pipes stay in step) and marks the pool broken."""
        for w, message in messages.items():
            if w == 0:
                continue
            try:
                self.conns[w].send(message)
            except (BrokenPipeError, OSError) as exc:
                self.broken = f"{self._where(w)} is gone ({exc})"
                raise WorkerError(f"{self._where(w)} is gone: it cannot take commands ({exc})") from None
        replies, error = {}, None
        if 0 in messages:
            try:
                replies[0] = _serve(*self.local, *messages[0])
            except Exception as exc:
                error = self._error(0, traceback.format_exc(), exc)
        for w in messages:
            if w == 0:
                continue
            conn, proc = self.conns[w], self.procs[w]
            try:
                ready = wait([conn, proc.sentinel])
                if conn not in ready and not conn.poll():
                    raise EOFError
                status, payload = conn.recv()
            except (EOFError, OSError):
                proc.join(1.0)
                error = error or WorkerError(f"{self._where(w)} died (exit code {proc.exitcode}) before replying; "
                                             "the vector environment cannot continue: close it and make a new one")
                continue
            if status == "error":
                error = error or self._error(w, *payload)
            else:
                replies[w] = cloudpickle.loads(payload) if messages[w][0] == "call" else payload
        if error is not None:
            self.broken = str(error).splitlines()[0]
            raise error
        return replies

    def _error(self, w: int, tb: str, exc) -> WorkerError:
        name = type(exc).__name__ if exc is not None else "an exception"
        err = WorkerError(f"{self._where(w)} raised {name}: {exc}\n--- traceback in the worker ---\n{tb}")
        err.__cause__ = exc
        return err

    def request(self, message) -> list:
        """The same command to every group; the replies in group order."""
        replies = self.run(dict.fromkeys(range(len(self.groups)), message))
        return [replies[w] for w in range(len(self.groups))]

    def close(self) -> None:
        """Ask each worker to stop, then terminate those that do not within the timeout; close group 0."""
        for conn, proc in zip(self.conns[1:], self.procs[1:]):
            if proc.is_alive():
                try:
                    conn.send(("close", None))
                except (BrokenPipeError, OSError):
                    pass
        for conn, proc in zip(self.conns[1:], self.procs[1:]):
            proc.join(_CLOSE_TIMEOUT_S)
            if proc.is_alive():
                proc.terminate()
                proc.join(_CLOSE_TIMEOUT_S)
            conn.close()
        local = getattr(self, "local", None)
        if local is not None:
            local[0].close()
            self.local = None
        self.conns, self.procs = [None], [None]


class CrowdVectorEnv(VectorEnv):
    """K copies of the crowd environment as one batch of slots (see the module docstring).

    Build it with :func:`vector_env` (K copies of the same options) or from ready environments with
    ``CrowdVectorEnv(envs)``: they must share observation, action and state spaces, agent count and
    decision interval (:class:`~crowd_env.errors.EnvOptionError` names the first difference).
    ``workers``: processes that step the copies (1: this process; at most K); ``start_method``: how
    they start (:data:`START_METHODS`).
    """

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": ["rgb_array"]}

    def __init__(self, envs, *, workers: int = 1, start_method: str = "spawn"):
        envs = list(envs)
        if not envs:
            raise EnvOptionError("a vector environment needs at least one copy")
        for k, e in enumerate(envs):
            if not isinstance(e, CrowdParallelEnv):
                raise EnvOptionError(f"copy {k} is a {type(e).__name__}, not a crowd_v0 CrowdParallelEnv")
        names = ("observation space", "action space", "number of agents", "decision interval dt_s", "state space",
                 "observation_frame")
        ref = _spaces_key(envs[0])
        for k, e in enumerate(envs[1:], 1):
            key = _spaces_key(e)
            for name, a, b in zip(names, ref, key):
                if a != b:
                    raise EnvOptionError(f"copy {k} does not match copy 0: its {name} is {b}, copy 0's is {a}")
        self.workers = _check_workers(workers, len(envs))
        if start_method not in START_METHODS or start_method not in multiprocessing.get_all_start_methods():
            raise EnvOptionError(f"start_method must be one of {[m for m in START_METHODS if m in multiprocessing.get_all_start_methods()]}, "
                                 f"got {start_method!r}")
        self.envs = envs
        self.n_copies = len(envs)
        self.n_agents = len(envs[0].possible_agents)
        self.num_envs = self.n_copies * self.n_agents
        first = envs[0].possible_agents[0]
        self.single_observation_space = envs[0].observation_space(first)
        self.single_action_space = envs[0].action_space(first)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.single_state_space = envs[0].state_space
        self.render_mode = envs[0].render_mode
        self.autoreset_mode = AutoresetMode.SAME_STEP
        self.slot_copy = np.repeat(np.arange(self.n_copies), self.n_agents)
        self.slot_agent = np.tile(np.arange(self.n_agents), self.n_copies)
        # the names of the reward's terms, the columns of infos["reward_terms"] (None: not reported)
        self.reward_term_names = envs[0].reward_term_names
        self._dim = (self.single_observation_space.shape[0], len(self.reward_term_names or ()))
        self._a_max = envs[0]._a_max_check
        self._started = False
        self._pool = None
        if self.workers == 1:
            self._copies = _Copies(envs, np.zeros(self.num_envs, bool))
            self._alive = self._copies.alive
        else:
            self._copies = None
            self._pool = _Workers(envs, self.workers, start_method, self.num_envs, self._dim, self.n_agents)
            self._alive = self._pool.views["alive"]

    # ------------------------------------------------------------------ API
    def _check_usable(self, what: str) -> None:
        if getattr(self, "closed", False):
            raise EnvStateError(f"{what} on a closed vector environment")
        if self._pool is not None and self._pool.broken:
            raise EnvStateError(f"{what}: a worker failed earlier ({self._pool.broken}); make a new vector environment")

    def reset(self, *, seed=None, options=None):
        """Reset every copy; returns ``(observations (K A, D), infos)``. ``seed``: an int
        s (copy c gets s + c), a list of K ints or None (continue each copy's stream)."""
        self._check_usable("reset()")
        if seed is None or not isinstance(seed, (list, tuple, np.ndarray)):
            seed = check_seed("seed", seed, error=EnvOptionError)
            seeds = [None if seed is None else seed + c for c in range(self.n_copies)]
        else:
            seeds = [check_seed(f"seed[{c}]", s, error=EnvOptionError) for c, s in enumerate(seed)]
            if len(seeds) != self.n_copies:
                raise EnvOptionError(f"reset(seed=...) needs one seed per copy ({self.n_copies}), got {len(seeds)}")
        if self._pool is None:
            out = _arrays(self.num_envs, self._dim)
            self._copies.reset(seeds, options, out)
        else:
            pool = self._pool
            pool.run({w: ("reset", ([seeds[c] for c in g], options)) for w, g in enumerate(pool.groups)})
            out = {k: v.copy() for k, v in pool.views.items()}
        self._started = True
        return out["obs"], self._infos(out)

    def _infos(self, out: dict) -> dict:
        infos = {"alive": self._alive.copy(), "acted": out["acted"], "copy": self.slot_copy.copy(),
                 "final_obs": out["final_obs"], "_final_obs": out["_final_obs"], "episode_return": out["episode_return"],
                 "episode_length": out["episode_length"], "episode_ended": out["episode_ended"]}
        if "reward_terms" in out:
            infos["reward_terms"] = out["reward_terms"]
        return infos

    def _check_actions(self, actions) -> np.ndarray:
        try:
            arr = real_actions(actions)
        except ActionError:
            raise
        except (TypeError, ValueError):
            raise ActionError(f"actions must be a numeric ({self.num_envs}, 2) array, got {type(actions).__name__}") from None
        if arr.shape != (self.num_envs, 2):
            raise ActionError(f"actions must have shape ({self.num_envs}, 2) (one velocity intent per slot: "
                              f"{self.n_copies} copies x {self.n_agents} agents), got {arr.shape}")
        live = self._alive
        if actions_within(arr, self._a_max, live):  # the usual case (NaN fails it)
            return arr
        bad = live & ~np.isfinite(arr).all(axis=1)
        if bad.any():
            raise ActionError(f"non-finite action(s) in live slot(s) {np.flatnonzero(bad)[:10].tolist()}")
        i = np.flatnonzero(live & (np.abs(arr) > self._a_max).any(axis=1))
        a = self.envs[0].action_max_m_s
        raise ActionError(f"action(s) of live slot(s) {i[:10].tolist()} outside the action space Box(-{a:g}, {a:g}) "
                          f"m/s: {arr[i[:10]].tolist()}; the environment does not clip")

    def step(self, actions):
        """One environment step of every copy; returns ``(obs, rewards, terminations, truncations, infos)`` as
        arrays over the slots (see the module docstring for padding slots and automatic resets)."""
        if not self._started:
            raise EnvStateError("call reset() before step()")
        self._check_usable("step()")
        arr = self._check_actions(actions)
        if self._pool is None:
            out = _arrays(self.num_envs, self._dim)
            self._copies.step(arr, out)
        else:
            pool = self._pool
            pool.views["actions"][:] = arr
            pool.request(("step", None))
            out = {k: v.copy() for k, v in pool.views.items()}
        return out["obs"], out["rewards"], out["terminated"], out["truncated"], self._infos(out)

    def state(self) -> np.ndarray:
        """The global state of every copy, ``(K, S)`` float32 (index it with ``slot_copy`` for the slots)."""
        if not self._started:
            raise EnvStateError("call reset() before state()")
        self._check_usable("state()")
        if self._pool is None:
            return self._copies.state()
        return np.concatenate(self._pool.request(("state", None)))

    def _by_worker(self, copies):
        """(worker, local copy indices, positions in ``copies``) for the copies each worker holds."""
        copies = list(range(self.n_copies)) if copies is None else [int(c) for c in copies]
        plan = []
        for w, g in enumerate(self._pool.groups):
            local = [(k, c - int(g[0])) for k, c in enumerate(copies) if g[0] <= c <= g[-1]]
            if local:
                plan.append((w, [c for _, c in local], [k for k, _ in local]))
        return copies, plan

    def call_copies(self, name: str, *args, copies=None, **kwargs) -> tuple:
        """``getattr(copy, name)(*args, **kwargs)`` of each copy in ``copies`` (default all; the attribute's
        value where it is not callable), in whichever process holds the copy."""
        self._check_usable(f"call({name!r})")
        if self._pool is None:
            return tuple(self._copies.call(range(self.n_copies) if copies is None else copies, name, args, kwargs))
        copies, plan = self._by_worker(copies)
        out = [None] * len(copies)
        replies = self._pool.run({w: ("call", (local, name, args, kwargs)) for w, local, _ in plan})
        for w, _, where in plan:
            for k, v in zip(where, replies[w]):
                out[k] = v
        return tuple(out)

    def call(self, name: str, *args, **kwargs) -> tuple:
        """Gymnasium's ``call``: the method ``name`` of every copy called with the arguments (or the attribute)."""
        return self.call_copies(name, *args, **kwargs)

    def get_attr(self, name: str) -> tuple:
        """The attribute ``name`` of every copy."""
        return self.call_copies(name)

    def set_attr(self, name: str, values, *, copies=None) -> None:
        """Set the attribute ``name`` of each copy in ``copies`` (default all): ``values`` one per copy, or one
        value for all when it is not a list or tuple."""
        self._check_usable(f"set_attr({name!r})")
        targets = list(range(self.n_copies)) if copies is None else [int(c) for c in copies]
        if not isinstance(values, (list, tuple)):
            values = [values] * len(targets)
        if len(values) != len(targets):
            raise EnvOptionError(f"set_attr({name!r}) needs one value per copy ({len(targets)}), got {len(values)}")
        if self._pool is None:
            self._copies.set_attr(targets, name, values)
            return
        _, plan = self._by_worker(targets)
        self._pool.run({w: ("set_attr", (local, name, [values[k] for k in where])) for w, local, where in plan})

    def render(self):
        """The ``rgb_array`` frame of every copy (a tuple), for copies made with ``render_mode="rgb_array"``."""
        return self.call_copies("render")

    def close_extras(self, **kwargs):
        pool = getattr(self, "_pool", None)
        if pool is not None:
            pool.close()
        for e in getattr(self, "envs", ()):  # also after a constructor that raised
            e.close()


def vector_env(copies: int = 1, *, workers: int = 1, start_method: str = "spawn", **options) -> CrowdVectorEnv:
    """K = ``copies`` copies of ``crowd_v0.parallel_env(**options)`` as one :class:`CrowdVectorEnv`, stepped in
    ``workers`` processes (1: this one; see the module docstring). The options are checked once, as one
    :class:`~crowd_env.envs.config.CrowdEnvConfig` that every copy is built from."""
    check_integer("copies", copies, error=EnvOptionError, minimum=1)
    _check_workers(workers, int(copies))
    config = make_config(None, options, "crowd_env.envs.vector", "vector_env")
    return CrowdVectorEnv([CrowdParallelEnv(config) for _ in range(int(copies))], workers=workers,
                          start_method=start_method)


def gym_vector_env(num_envs: int = 1, *, learner="ped_0", max_episode_steps=None, **options) -> CrowdVectorEnv:
    """The vector entry point of the Gymnasium ids (:mod:`crowd_env.registration`), which
    ``gymnasium.make_vec(id, num_envs)`` calls: ``num_envs`` copies of the single-agent view's environment
    (:class:`~crowd_env.envs.gym_single.CrowdSingleAgentEnv`: pedestrian ``learner`` controlled, the others on
    the background policy), so that slot c is copy c's learner, seeded ``seed + c`` as Gymnasium's own vector
    environments seed theirs. ``max_episode_steps`` (Gymnasium's time limit; ``make_vec`` passes the spec's)
    truncates at the smaller of it and ``max_steps``, as ``gymnasium.make``'s ``TimeLimit`` does. Other options
    (``workers`` and ``start_method`` too) as in :func:`vector_env`."""
    if "controlled" in options:
        raise EnvOptionError("the Gymnasium ids control exactly one pedestrian per copy: pass learner=..., not "
                             "controlled=...")
    options = resolve_options(options, "the crowd_env Gymnasium ids", "gymnasium.make_vec",
                              extra=("workers", "start_method"))
    if max_episode_steps is not None:
        check_integer("max_episode_steps", max_episode_steps, error=EnvOptionError, minimum=1)
        steps = options.get("max_steps")
        options["max_steps"] = int(max_episode_steps) if steps is None else min(int(steps), int(max_episode_steps))
    return vector_env(num_envs, controlled=[learner], **options)

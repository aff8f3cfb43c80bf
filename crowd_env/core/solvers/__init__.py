"""The contact solvers of the Kabalan et al. (2016) model: one module per method, one object choosing.

* :mod:`~crowd_env.core.solvers.status`: the status codes every solver returns (when none serves, the cascade raises :class:`~crowd_env.errors.SimulationError`);
* :mod:`~crowd_env.core.solvers.linalg`: the compiled Cholesky kernels every dense solver uses;
* :mod:`~crowd_env.core.solvers.graph`: the contact graph (clusters, orderings, keys) and its operators;
* :mod:`~crowd_env.core.solvers.pivoting`: the dense pivoting LCP;
* :mod:`~crowd_env.core.solvers.impact`: the dense Frémond impact (Eq. 4-8) and the compiled impact stage;
* :mod:`~crowd_env.core.solvers.dense_projection`: the dense gap projection;
* :mod:`~crowd_env.core.solvers.sparse_qp`: sparse pivoting (SuperLU) for large impacts and projections;
* :mod:`~crowd_env.core.solvers.large_projection`: augmented Lagrangian, interior point, working set;
* :mod:`~crowd_env.core.solvers.external`: PIQP and Clarabel (optional extra ``solvers``);
* :mod:`~crowd_env.core.solvers.reference`: the cvxpy reference impact (tests, ``solver="cvxpy"``);
* :mod:`~crowd_env.core.solvers.closed_form`: the paper's closed-form impacts (Section 3);
* :mod:`~crowd_env.core.solvers.cascade`: :class:`SolverCascade`, the choice between them.

A solver module imports only the shared modules (``status``, ``linalg``, ``graph``), the public names of
sibling solvers it builds on, and :mod:`crowd_env.core.contacts`; only ``cascade`` chooses between methods.
"""
from .cascade import SolverCascade
from crowd_env.errors import SimulationError

__all__ = ["SolverCascade", "SimulationError"]

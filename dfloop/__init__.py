"""dfloop: describing-function prediction of limit cycles in nonlinear feedback loops."""
from .describing import *  # noqa: F401,F403
from .impact import *  # noqa: F401,F403
from .solve import *  # noqa: F401,F403
from .verify import simulate_loop, verify_cycle  # noqa: F401

__version__ = "0.1.0"

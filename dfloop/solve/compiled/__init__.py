"""The compiled prediction pipeline (numba): rational G with an optional pure delay and the built-in static
elements with closed-form DFs. See :mod:`.residual` for where it applies and how it is switched off."""
from .residual import (CompiledResidual, compiled_loop, driver_parts, driver_wanted, element_form, enabled, mode, prepare,
                       residual_for, run_batch, run_driver, warmup)

__all__ = ["CompiledResidual", "compiled_loop", "driver_parts", "driver_wanted", "element_form", "enabled", "mode", "prepare",
           "residual_for", "run_batch", "run_driver", "warmup"]

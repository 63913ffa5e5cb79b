"""Kind codes of the elements with a compiled form (the names their ``compiled_form()`` returns); no numba here,
so deciding whether a loop can be compiled loads nothing."""
SATURATION, DEADZONE, RELAY, BACKLASH, CUBIC, PRELOAD, FRICTION = range(7)
KINDS = {"saturation": SATURATION, "dead_zone": DEADZONE, "relay": RELAY, "backlash": BACKLASH,
         "cubic": CUBIC, "preload": PRELOAD, "friction": FRICTION}

"""dfloop.impact"""
__all__: list[str] = []

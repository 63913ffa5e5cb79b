"""dfloop.plot"""
__all__: list[str] = []

"""dfloop.solve"""
__all__: list[str] = []

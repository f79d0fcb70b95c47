def write_scene(*a, **k): raise NotImplementedError

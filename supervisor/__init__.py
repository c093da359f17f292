"""The Sabo supervisor: the code behind the `./sabo` front-door script.

It installs and builds the project (`setup`), runs the test suite (`test`) and
supervises a coupled run (`run`): it starts the coupler and the solvers a scene
needs, shows progress, and never leaves a process or a hung run behind.
Python standard library only; runs under any python3 >= 3.8.
"""

from __future__ import annotations

"""A plan's output folder: checked before any solving, written whole or not at all.

A plan takes minutes to hours; a folder that turns out unwritable after the solve loses
it, and a plan written file by file into a folder that held another one mixes the two
when it is interrupted. So `OutputFolder.check()` runs before the solve (the folder is a
folder, writable, and holds no earlier plan unless `force`), the plan is written into a
staging folder beside the target (same file system, so the final move is a rename), and
`publish` moves it into place at once. An interrupted or failed run removes its staging
folder and leaves the target as it was.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from tfcontact.errors import InvalidInput
from tfcontact.interrupt import raise_if_signalled, signals_deferred


def _nearest_existing(path: Path) -> Path:
    for candidate in (path, *path.parents):
        if candidate.exists() or candidate.is_symlink():
            return candidate
    return Path(".")


@dataclass(frozen=True)
class OutputFolder:
    """The folder a plan is written to.

    Args:
        target: the folder (created if missing, with its parents).
        force: replace a folder that already holds files (an earlier plan); without it
            such a folder is refused before solving, so no plan is overwritten unasked.
    """

    target: Path
    force: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "target", Path(self.target))

    def check(self) -> None:
        """Refuse, before any solving, a target that cannot take the plan.

        Raises:
            InvalidInput: the target (or a folder above it) is a file, is not writable,
                or holds files and `force` is not set; the message names the fix.
        """
        target = self.target
        existing = _nearest_existing(target)
        if existing.is_file() or (existing.exists() and not existing.is_dir()):
            where = "is a file" if existing == target else f"lies below the file {existing}"
            raise InvalidInput(f"output folder {target} {where}: give a folder with --out")
        if existing == target:
            if any(target.iterdir()) and not self.force:
                raise InvalidInput(
                    f"output folder {target} already holds files (an earlier plan?): pass "
                    "--force to replace them, or give another folder with --out")
            if not os.access(target, os.W_OK | os.X_OK):
                raise InvalidInput(f"output folder {target} is not writable: give a "
                                   "writable folder with --out, or change its permissions")
            existing = target.parent if target.parent != target else target
        # The staging folder and the final rename need the parent to be writable.
        if not os.access(existing, os.W_OK | os.X_OK):
            raise InvalidInput(f"cannot create the output folder {target}: {existing} is not "
                               "writable; give a writable folder with --out")

    @contextmanager
    def staging(self) -> Iterator[Path]:
        """A fresh folder beside the target to write the plan into; on a normal exit it
        replaces the target at once (`publish`), on an exception (an interrupt, a
        failure to write) it is removed and the target stays as it was."""
        self.check()
        parent = self.target.parent
        try:
            parent.mkdir(parents=True, exist_ok=True)
            stage = Path(tempfile.mkdtemp(prefix=f".{self.target.name}.partial-", dir=parent))
        except OSError as error:
            raise InvalidInput(f"cannot create the output folder {self.target}: "
                               f"{error.strerror}; give a writable folder with --out") from error
        try:
            yield stage
            # A signal whose exception a native call swallowed still keeps the old folder.
            raise_if_signalled()
        except BaseException:
            shutil.rmtree(stage, ignore_errors=True)
            raise
        self.publish(stage)

    def publish(self, stage: Path) -> None:
        """Move the written folder `stage` to the target; an existing target (checked
        replaceable) is renamed aside first and removed after the move."""
        os.chmod(stage, 0o777 & ~_umask())  # mkdtemp makes 0700 folders
        target = self.target
        if not target.exists():
            os.rename(stage, target)
            return
        aside = Path(tempfile.mkdtemp(prefix=f".{target.name}.replaced-", dir=target.parent))
        # A Ctrl-C between the two renames would leave no folder at the target, and one
        # before the removal the old plan aside: it waits.
        with signals_deferred():
            os.rename(target, aside / target.name)
            os.rename(stage, target)
            shutil.rmtree(aside, ignore_errors=True)

    def final_path(self, path: Path, stage: Path) -> Path:
        """Where a file written below `stage` lies after `publish`."""
        return self.target / Path(path).relative_to(stage)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask

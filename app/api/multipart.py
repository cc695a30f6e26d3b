"""Reading a multipart upload with its file part in memory: one growing buffer.

Starlette's ``request.form()`` spools a file part to a temporary file that rolls to disk past
1 MB, with a thread-pool hop for every chunk written, and the route then reads it back (a
copy): about 1 s for a 135 MB log. Here the file part's bytes go straight into one
``bytearray`` as they arrive (like the JSON path's body). Everything else is Starlette's
parser (python-multipart underneath): the same limits on files, fields and field sizes, the
same messages, answered 400 as ``request.form()`` answers them. The body's size limit (413) is
the middleware's, on the stream read here.

The buffering hooks rely on the parser's internals (``_current_part``, ``items``). Where a
Starlette release no longer has them (``BUFFERING``), uploads go through ``request.form()``
and the file part is read into a :class:`BufferedUpload` afterwards: slower, still correct,
and ``tests/api/test_multipart.py`` fails, saying so.
"""

from __future__ import annotations

import io
import logging

from starlette.datastructures import FormData, Headers, UploadFile
from starlette.exceptions import HTTPException
from starlette.formparsers import MultiPartException, MultiPartParser
from starlette.requests import Request

log = logging.getLogger(__name__)


class BufferedUpload(UploadFile):
    """A file part read into memory: ``buffer`` holds its bytes."""

    def __init__(self, filename: str | None, headers: Headers) -> None:
        super().__init__(file=io.BytesIO(), size=0, filename=filename, headers=headers)
        self.buffer = bytearray()


class _BufferingParser(MultiPartParser):
    def on_headers_finished(self) -> None:
        super().on_headers_finished()  # names, counts and limits the part
        part = self._current_part
        if part.file is not None:
            spooled = part.file
            spooled.file.close()  # never written: nothing on disk
            part.file = BufferedUpload(spooled.filename, spooled.headers)

    def on_part_data(self, data: bytes, start: int, end: int) -> None:
        file = self._current_part.file
        if isinstance(file, BufferedUpload):
            file.buffer += memoryview(data)[start:end]
        else:
            super().on_part_data(data, start, end)

    def on_part_end(self) -> None:
        part = self._current_part
        if isinstance(part.file, BufferedUpload):
            part.file.size = len(part.file.buffer)
            self.items.append((part.field_name, part.file))
        else:
            super().on_part_end()


def _parser_has_hooks() -> bool:
    """Whether Starlette's parser still keeps what the buffering hooks use."""
    names = set(getattr(getattr(MultiPartParser.__init__, "__code__", None), "co_names", ()))
    hooks = ("on_headers_finished", "on_part_data", "on_part_end", "parse")
    return {"_current_part", "items"} <= names and all(
        callable(getattr(MultiPartParser, h, None)) for h in hooks
    )


BUFFERING = _parser_has_hooks()
"""Whether file parts are read straight into memory (else via ``request.form()``)."""
if not BUFFERING:
    log.warning(
        "this Starlette's multipart parser lacks the hooks app/api/multipart.py uses: uploads "
        "are spooled by request.form() (slower for large logs)"
    )


async def _read_form_spooled(request: Request, *, max_files: int, max_fields: int) -> FormData:
    """``request.form()`` with its file parts read into :class:`BufferedUpload` objects."""
    form = await request.form(max_files=max_files, max_fields=max_fields)
    items: list[tuple[str, str | UploadFile]] = []
    for key, value in form.multi_items():
        if isinstance(value, UploadFile):
            buffered = BufferedUpload(value.filename, value.headers)
            while chunk := await value.read(1 << 20):
                buffered.buffer += chunk
            buffered.size = len(buffered.buffer)
            await value.close()
            items.append((key, buffered))
        else:
            items.append((key, value))
    return FormData(items)


async def read_form(request: Request, *, max_files: int, max_fields: int) -> FormData:
    """The request's multipart form, file parts as :class:`BufferedUpload`.

    Raises
    ------
    HTTPException
        400 with python-multipart's/Starlette's message when the body is not a valid form or
        exceeds ``max_files``, ``max_fields`` or the size of a text field.
    """
    if not BUFFERING:
        return await _read_form_spooled(request, max_files=max_files, max_fields=max_fields)
    parser = _BufferingParser(
        request.headers, request.stream(), max_files=max_files, max_fields=max_fields
    )
    try:
        return await parser.parse()
    except MultiPartException as exc:
        raise HTTPException(status_code=400, detail=exc.message) from None

"""The few PETSc C functions petsc4py does not wrap, called through ctypes on the same libpetsc."""
import ctypes
import os

_lib = None


def lib():
    global _lib
    if _lib is None:
        import glob
        import petsc4py
        cfg = petsc4py.get_config()
        d = os.path.join(cfg["PETSC_DIR"], cfg.get("PETSC_ARCH") or "", "lib")
        # the wheel ships libpetsc.so as a stub; the real library is libpetsc.so.X.Y (the largest file)
        path = max(glob.glob(os.path.join(d, "libpetsc.so*")), key=os.path.getsize)
        _lib = ctypes.CDLL(path)
        _lib.SNESSetFunctionDomainError.argtypes = [ctypes.c_void_p]
        _lib.PetscErrorMessage.argtypes = [ctypes.c_int, ctypes.POINTER(ctypes.c_char_p),
                                           ctypes.POINTER(ctypes.c_char_p)]
    return _lib


def set_function_domain_error(snes):
    """SNESSetFunctionDomainError: the residual was asked for outside the material's domain
    (an inverted element for Neo-Hookean); SNES then stops with DIVERGED_FUNCTION_DOMAIN."""
    lib().SNESSetFunctionDomainError(ctypes.c_void_p(snes.handle))


def error_message(code):
    """PETSc's text for an error code, and the specific message of the last error raised."""
    text, specific = ctypes.c_char_p(), ctypes.c_char_p()
    try:
        lib().PetscErrorMessage(int(code), ctypes.byref(text), ctypes.byref(specific))
    except Exception:
        return f"PETSc error {code}"
    parts = [p.decode(errors="replace").strip() for p in (text.value, specific.value) if p]
    return ": ".join(parts) or f"PETSc error {code}"

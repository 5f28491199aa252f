/*
 * module.c - makes the simulator's shared library importable as ultraglide.devices.firmware._sil (an empty
 * module), so Python finds it like any extension; devices/firmware/sil.py then loads the same file with ctypes
 * and calls the ug_sim_* functions. Not part of the firmware: the board build never sees it.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

static struct PyModuleDef sil_module = {
    PyModuleDef_HEAD_INIT, "_sil",
    "The firmware core and the simulator's port, for ctypes (see ultraglide.devices.firmware.sil).", -1, NULL,
    NULL, NULL, NULL, NULL,
};

PyMODINIT_FUNC PyInit__sil(void) { return PyModule_Create(&sil_module); }

/* The Master type of plem.control._core (master_binding.c), for the module and the Core that cycles through it. */
#ifndef PLEM_MASTER_BINDING_H
#define PLEM_MASTER_BINDING_H

#include <Python.h>

#include "master.h"

extern PyTypeObject PLEM_MASTER_TYPE;

/* The plem_master of a Master object; NULL with a TypeError for anything else. */
plem_master *plem_master_of(PyObject *object);
/* Add Master, SdoError, al_status_text and IOMAP_BYTES to the module; -1 with an exception on failure. */
int plem_add_master(PyObject *module);

#endif

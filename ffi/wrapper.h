/* Headers bindgen reads (PETSc/SLEPc 3.18 as packaged by Debian 12). */
#include <mpi.h>
#include <petscsys.h>
#include <petscmat.h>
#include <petscvec.h>
#include <petscviewer.h>
#include <slepceps.h>

/* sepbrdf: separable BRDF approximations (umbrella header). */
#ifndef SEPBRDF_SEPBRDF_H
#define SEPBRDF_SEPBRDF_H

#include "channels.h"
#include "common.h"
#include "estimate.h"
#include "exr.h"
#include "factor.h"
#include "glsl.h"
#include "image.h"
#include "job.h"
#include "matrix.h"
#include "measured.h"
#include "models.h"
#include "outset.h"
#include "param.h"
#include "render.h"
#include "sampler.h"
#include "scene.h"
#include "solver.h"
#include "source.h"
#include "svd.h"
#include "viewer.h"

#endif

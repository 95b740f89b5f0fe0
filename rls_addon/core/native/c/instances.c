/* A top-level Embree scene's instances attached in C (rls_attach_instances): each an
 * Embree scene placed by its transforms at evenly spaced time steps, a sweep through
 * traffic sets about a thousand of them, one ctypes call each from Python.
 *
 * rls_addon/core/casting/embree_api.py (_MotionScene._attach_each) is the readable
 * reference this follows call by call, in the same order and with the same arguments:
 * per instance rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE),
 * rtcSetGeometryInstancedScene, rtcSetGeometryTimeStepCount, rtcSetGeometryTransform
 * per step (3x4 row-major float32 rows, read by Embree, which copies them), then
 * rtcCommitGeometry, rtcAttachGeometry, rtcReleaseGeometry. The caller commits the
 * scene. As in embree_loop.c no Embree header is needed: the caller passes the entry
 * points of the libembree4 that the embreex wheel loaded. */
#include <stdint.h>

#include "rls_threads.h"

#define RLS_INSTANCES_ABI 1
#define GEOMETRY_TYPE_INSTANCE 121
#define FORMAT_FLOAT3X4_ROW_MAJOR 0x9134

typedef struct {
    void *(*new_geometry)(void *device, int type);
    void (*set_instanced_scene)(void *geometry, void *scene);
    void (*set_time_step_count)(void *geometry, unsigned int count);
    void (*set_transform)(void *geometry, unsigned int step, int format, const void *xfm);
    void (*commit_geometry)(void *geometry);
    unsigned int (*attach_geometry)(void *scene, void *geometry);
    void (*release_geometry)(void *geometry);
} embree_calls_t;

typedef struct {
    const embree_calls_t *calls;
    void *device, *scene;   /* the top-level scene, not committed */
    int64_t count;          /* instances */
    void *const *scenes;    /* per instance: the Embree scene it places */
    const int64_t *steps;   /* per instance: its time steps (>= 1) */
    const float *rows;      /* every step's 3x4 row-major matrix, instance by instance */
} instances_t;

/* Returns the instances attached: fewer than count when Embree gave no geometry. */
RLS_EXPORT int64_t rls_attach_instances(const instances_t *a) {
    const embree_calls_t *c = a->calls;
    int64_t first = 0;
    for (int64_t i = 0; i < a->count; i++) {
        void *geom = c->new_geometry(a->device, GEOMETRY_TYPE_INSTANCE);
        if (geom == NULL) return i;
        c->set_instanced_scene(geom, a->scenes[i]);
        c->set_time_step_count(geom, (unsigned int)a->steps[i]);
        for (int64_t k = 0; k < a->steps[i]; k++)
            c->set_transform(geom, (unsigned int)k, FORMAT_FLOAT3X4_ROW_MAJOR,
                             a->rows + 12 * (first + k));
        first += a->steps[i];
        c->commit_geometry(geom);
        c->attach_geometry(a->scene, geom);
        c->release_geometry(geom);
    }
    return a->count;
}

/* The interface version of rls_attach_instances (RLS_INSTANCES_ABI). */
RLS_EXPORT int rls_instances_abi(void) {
    return RLS_INSTANCES_ABI;
}

#pragma once
/* The C interface of libhandskin_step.so (step_module.cpp), loaded by export/step.cpp. */
#ifdef __cplusplus
extern "C" {
#endif

typedef struct HsStepSummary {
  int faces;          /* faces in the shape */
  int shells;         /* shells */
  int closed_shells;  /* of which closed */
  int solids;         /* solids (a closed shell is written as one) */
  int free_edges;     /* edges bounding one face only (0 on a closed shell) */
  int valid;          /* 1 when OCCT's BRepCheck finds the shape valid */
  double box[6];      /* bounding box: xmin, ymin, zmin, xmax, ymax, zmax (mm) */
  char error[512];    /* why, when a call returns nonzero */
} HsStepSummary;

/* Writes n_patches bicubic Bézier patches (poles: n_patches × 16 × 3 doubles, P[4i + j] with
   u along i; names: one per patch) to `path` as STEP AP214 in mm, sewn at sew_tolerance_mm.
   Returns 0, or nonzero with out->error; out->faces is the faces written (read the file back
   with handskin_step_read for its shape). */
int handskin_step_write(int n_patches, const double* poles, const char* const* names, const char* path,
                        double sew_tolerance_mm, HsStepSummary* out);

/* Reads a STEP file back and summarises it; `names` (if given) receives the faces' names, one
   per line, cut at names_size. Returns 0, or nonzero with out->error. */
int handskin_step_read(const char* path, HsStepSummary* out, char* names, int names_size);

#ifdef __cplusplus
}
#endif

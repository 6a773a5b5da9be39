/* VTK trajectory frames for ParaView (docs/cli.md "VTK"): XML PolyData
 * (.vtp, ASCII inline data so every file stays well-formed XML), the legacy
 * format (.vtk) and the .pvd series file that lists the frames with their
 * times. Particles are points, springs lines; 2-D systems get z = 0. */
#include "mpi/mpi.h"

#include <stdio.h>

/* Component k of point i in 3-D (0 past dim). */
static double comp(const double *a, int dim, size_t i, int k)
{
    return k < dim ? a[i * (size_t)dim + (size_t)k] : 0.0;
}

static size_t spring_count(const psys_system *sys)
{
    return sys->springs ? psys__springs_count(sys->springs) : 0;
}

static int write_vec3(FILE *fp, const double *a, int dim, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (fprintf(fp, "%.17g %.17g %.17g\n", comp(a, dim, i, 0), comp(a, dim, i, 1), comp(a, dim, i, 2)) < 0)
            return -1;
    return 0;
}

int psys_vtp_write_frame(FILE *fp, const psys_system *sys, long long step)
{
    size_t n = sys->n, ns = spring_count(sys);
    int d = sys->dim;
    if (fprintf(fp,
                "<?xml version=\"1.0\"?>\n"
                "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
                "  <PolyData>\n"
                "    <FieldData>\n"
                "      <DataArray type=\"Float64\" Name=\"TimeValue\" NumberOfTuples=\"1\" format=\"ascii\">%.17g</DataArray>\n"
                "      <DataArray type=\"Int64\" Name=\"step\" NumberOfTuples=\"1\" format=\"ascii\">%lld</DataArray>\n"
                "    </FieldData>\n"
                "    <Piece NumberOfPoints=\"%zu\" NumberOfVerts=\"%zu\" NumberOfLines=\"%zu\" NumberOfStrips=\"0\" "
                "NumberOfPolys=\"0\">\n"
                "      <PointData Scalars=\"mass\" Vectors=\"velocity\">\n"
                "        <DataArray type=\"Float64\" Name=\"velocity\" NumberOfComponents=\"3\" format=\"ascii\">\n",
                sys->t, step, n, n, ns) < 0)
        return -1;
    if (write_vec3(fp, sys->v, d, n) != 0)
        return -1;
    if (fputs("        </DataArray>\n"
              "        <DataArray type=\"Float64\" Name=\"mass\" format=\"ascii\">\n", fp) < 0)
        return -1;
    for (size_t i = 0; i < n; i++)
        if (fprintf(fp, "%.17g\n", sys->mass[i]) < 0)
            return -1;
    if (fputs("        </DataArray>\n"
              "        <DataArray type=\"UInt8\" Name=\"flags\" format=\"ascii\">\n", fp) < 0)
        return -1;
    for (size_t i = 0; i < n; i++)
        if (fprintf(fp, "%u\n", (unsigned)(sys->flags[i] & PSYS_PARTICLE_NOT_FREE)) < 0)
            return -1;
    if (fputs("        </DataArray>\n"
              "        <DataArray type=\"Int64\" Name=\"index\" format=\"ascii\">\n", fp) < 0)
        return -1;
    for (size_t i = 0; i < n; i++)
        if (fprintf(fp, "%zu\n", i) < 0)
            return -1;
    if (fputs("        </DataArray>\n"
              "      </PointData>\n"
              "      <Points>\n"
              "        <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n", fp) < 0)
        return -1;
    if (write_vec3(fp, sys->x, d, n) != 0)
        return -1;
    if (fputs("        </DataArray>\n"
              "      </Points>\n"
              "      <Verts>\n"
              "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n", fp) < 0)
        return -1;
    for (size_t i = 0; i < n; i++)
        if (fprintf(fp, "%zu\n", i) < 0)
            return -1;
    if (fputs("        </DataArray>\n"
              "        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n", fp) < 0)
        return -1;
    for (size_t i = 0; i < n; i++)
        if (fprintf(fp, "%zu\n", i + 1) < 0)
            return -1;
    if (fputs("        </DataArray>\n"
              "      </Verts>\n"
              "      <Lines>\n"
              "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n", fp) < 0)
        return -1;
    for (size_t k = 0; k < ns; k++) {
        size_t a, b;
        psys__springs_get(sys->springs, k, &a, &b, NULL, NULL, NULL);
        if (fprintf(fp, "%zu %zu\n", a, b) < 0)
            return -1;
    }
    if (fputs("        </DataArray>\n"
              "        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n", fp) < 0)
        return -1;
    for (size_t k = 0; k < ns; k++)
        if (fprintf(fp, "%zu\n", 2 * (k + 1)) < 0)
            return -1;
    return fputs("        </DataArray>\n"
                 "      </Lines>\n"
                 "    </Piece>\n"
                 "  </PolyData>\n"
                 "</VTKFile>\n", fp) < 0 ? -1 : 0;
}

int psys_vtk_write_frame(FILE *fp, const psys_system *sys, long long step)
{
    size_t n = sys->n, ns = spring_count(sys);
    int d = sys->dim;
    if (fprintf(fp,
                "# vtk DataFile Version 3.0\n"
                "psys step %lld t %.17g\n"
                "ASCII\n"
                "DATASET POLYDATA\n"
                "FIELD FieldData 2\n"
                "TIME 1 1 double\n%.17g\n"
                "CYCLE 1 1 long\n%lld\n"
                "POINTS %zu double\n",
                step, sys->t, sys->t, step, n) < 0)
        return -1;
    if (write_vec3(fp, sys->x, d, n) != 0)
        return -1;
    if (n && fprintf(fp, "VERTICES %zu %zu\n", n, 2 * n) < 0)
        return -1;
    for (size_t i = 0; i < n; i++)
        if (fprintf(fp, "1 %zu\n", i) < 0)
            return -1;
    if (ns && fprintf(fp, "LINES %zu %zu\n", ns, 3 * ns) < 0)
        return -1;
    for (size_t k = 0; k < ns; k++) {
        size_t a, b;
        psys__springs_get(sys->springs, k, &a, &b, NULL, NULL, NULL);
        if (fprintf(fp, "2 %zu %zu\n", a, b) < 0)
            return -1;
    }
    if (!n)
        return 0;
    if (fprintf(fp, "POINT_DATA %zu\nVECTORS velocity double\n", n) < 0 || write_vec3(fp, sys->v, d, n) != 0)
        return -1;
    if (fputs("SCALARS mass double 1\nLOOKUP_TABLE default\n", fp) < 0)
        return -1;
    for (size_t i = 0; i < n; i++)
        if (fprintf(fp, "%.17g\n", sys->mass[i]) < 0)
            return -1;
    /* More arrays go in a field: legacy readers keep only one SCALARS section by default. */
    if (fprintf(fp, "FIELD FieldData 1\nflags 1 %zu int\n", n) < 0)
        return -1;
    for (size_t i = 0; i < n; i++)
        if (fprintf(fp, "%u\n", (unsigned)(sys->flags[i] & PSYS_PARTICLE_NOT_FREE)) < 0)
            return -1;
    return 0;
}

int psys_pvd_write_header(FILE *fp)
{
    return fputs("<?xml version=\"1.0\"?>\n"
                 "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
                 "  <Collection>\n", fp) < 0 ? -1 : 0;
}

int psys_pvd_write_entry(FILE *fp, double t, const char *file)
{
    if (fprintf(fp, "    <DataSet timestep=\"%.17g\" group=\"\" part=\"0\" file=\"", t) < 0)
        return -1;
    for (const char *c = file; *c; c++) {
        int rc;
        switch (*c) {
        case '&': rc = fputs("&amp;", fp); break;
        case '<': rc = fputs("&lt;", fp); break;
        case '>': rc = fputs("&gt;", fp); break;
        case '"': rc = fputs("&quot;", fp); break;
        case '\'': rc = fputs("&apos;", fp); break;
        default: rc = fputc(*c, fp); break;
        }
        if (rc < 0)
            return -1;
    }
    return fputs("\"/>\n", fp) < 0 ? -1 : 0;
}

int psys_pvd_write_footer(FILE *fp)
{
    return fputs("  </Collection>\n</VTKFile>\n", fp) < 0 ? -1 : 0;
}

/* Draco .drc meshes through Draco's decoder.
 *
 * Draco stores attribute values apart from the points that use them (a point
 * maps to one value per attribute), so each point becomes one of our
 * vertices, with its position, normal and UV looked up through that map. The
 * decoder has already undone quantization; ConvertValue gives floats. Faces
 * are kept in Draco's order: the decoded mesh is the scene, and Draco
 * itself removed index-degenerate faces when it encoded it.
 */
#include <draco/compression/config/compression_shared.h>
#include <draco/compression/decode.h>
#include <draco/compression/point_cloud/point_cloud_decoder.h>
#include <draco/core/varint_decoding.h>
#include <draco/mesh/mesh.h>
#include <draco/metadata/geometry_metadata.h>
#include <draco/metadata/metadata_decoder.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <memory>
#include <new>

extern "C" {
#include "as_internal.h"
}
#include "mesh_import_shims.h"

namespace {

/* Fills `out` (components floats per point) from a per-point attribute. */
bool copy_attribute(const draco::PointAttribute &att, uint32_t points, int components, float *out)
{
    for (uint32_t p = 0; p < points; ++p) {
        const draco::AttributeValueIndex v = att.mapped_index(draco::PointIndex(p));
        if (!att.ConvertValue<float>(v, int8_t(components), out + size_t(p) * components))
            return false;
    }
    return true;
}

/* An attribute is kept only when it has the components we store, in a
 * numeric type: Draco converts a DT_BOOL attribute by loading its raw bytes
 * as bool, which is undefined for any byte but 0 and 1, and a file may hold
 * any byte there. */
const draco::PointAttribute *usable(const draco::Mesh &m, draco::GeometryAttribute::Type type,
                                    int components)
{
    const draco::PointAttribute *att = m.GetNamedAttribute(type);
    if (!att || att->num_components() < components) return nullptr;
    switch (att->data_type()) {
    case draco::DT_INT8: case draco::DT_UINT8: case draco::DT_INT16: case draco::DT_UINT16:
    case draco::DT_INT32: case draco::DT_UINT32: case draco::DT_INT64: case draco::DT_UINT64:
    case draco::DT_FLOAT32: case draco::DT_FLOAT64:
        return att;
    default:
        return nullptr;
    }
}

/* A count of the connectivity as the decoder reads it: before 2.0 four
 * bytes, then a varint. */
bool connectivity_count(draco::DecoderBuffer *b, uint16_t version, uint32_t *v)
{
    if (version < DRACO_BITSTREAM_VERSION(2, 0)) return b->Decode(v);
    return draco::DecodeVarint(v, b);
}

/* Draco's decoder sizes its tables from the face and vertex counts at the
 * head of a mesh's connectivity before it decodes any of it: a file of 180
 * bytes claiming 600 million faces made it take 14 GB and 37 s before it
 * failed. The counts are read here as the decoder reads them (header,
 * metadata, then the method's fields) and refused when no mesh that size
 * could fit the file: real files hold 0.5 to 2.5 faces per byte, the bound
 * is 256 per byte and a million more. Anything this reading cannot follow
 * is left to the decoder, which fails on it as well. */
as_error_t draco_counts_fit(const void *data, size_t size, const char *name)
{
    draco::DecoderBuffer b;
    b.Init(static_cast<const char *>(data), size);
    draco::DracoHeader header;
    if (!draco::PointCloudDecoder::DecodeHeader(&b, &header).ok() || header.encoder_type != draco::TRIANGULAR_MESH)
        return AS_OK;
    const uint16_t version = DRACO_BITSTREAM_VERSION(header.version_major, header.version_minor);
    b.set_bitstream_version(version);
    if (version >= DRACO_BITSTREAM_VERSION(1, 3) && (header.flags & METADATA_FLAG_MASK)) {
        draco::GeometryMetadata metadata;
        draco::MetadataDecoder decoder;
        if (!decoder.DecodeGeometryMetadata(&b, &metadata)) return AS_OK;
    }
    uint64_t faces, vertices;
    if (header.encoder_method == draco::MESH_EDGEBREAKER_ENCODING) {
        uint8_t traversal;
        uint32_t new_vertices = 0, encoded_vertices, face_count, symbols, split_symbols;
        uint8_t attribute_data;
        if (!b.Decode(&traversal)) return AS_OK;
        if (version < DRACO_BITSTREAM_VERSION(2, 2) && !connectivity_count(&b, version, &new_vertices)) return AS_OK;
        if (!connectivity_count(&b, version, &encoded_vertices) || !connectivity_count(&b, version, &face_count) ||
            !b.Decode(&attribute_data) || !connectivity_count(&b, version, &symbols) ||
            !connectivity_count(&b, version, &split_symbols))
            return AS_OK;
        faces = face_count;
        vertices = uint64_t(encoded_vertices) + split_symbols + new_vertices;
    } else if (header.encoder_method == draco::MESH_SEQUENTIAL_ENCODING) {
        uint32_t face_count, points;
        if (version < DRACO_BITSTREAM_VERSION(2, 2)) {
            if (!b.Decode(&face_count) || !b.Decode(&points)) return AS_OK;
        } else if (!draco::DecodeVarint(&face_count, &b) || !draco::DecodeVarint(&points, &b)) {
            return AS_OK;
        }
        faces = face_count;
        vertices = points;
    } else {
        return AS_OK;
    }
    const uint64_t most = (uint64_t(1) << 20) + 256 * uint64_t(size);
    if (faces > most || vertices > most)
        return as_set_error(AS_ERROR_PARSE,
                            "%s: cannot decode as Draco: its connectivity claims %llu faces and %llu vertices, "
                            "more than %zu bytes can hold",
                            name, (unsigned long long)faces, (unsigned long long)vertices, size);
    return AS_OK;
}

as_error_t read_draco(const void *data, size_t size, const char *name, as_mesh_t *mesh)
{
    const as_error_t fits = draco_counts_fit(data, size, name);
    if (fits != AS_OK) return fits;
    draco::DecoderBuffer buffer;
    buffer.Init(static_cast<const char *>(data), size);
    draco::Decoder decoder;
    auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
    if (!decoded.ok())
        return as_set_error(AS_ERROR_PARSE, "%s: cannot decode as Draco: %s", name,
                            decoded.status().error_msg());
    const draco::Mesh &m = *decoded.value();

    const uint64_t points = m.num_points();
    const uint64_t faces = m.num_faces();
    if (points > UINT32_MAX || faces > UINT32_MAX)
        return as_set_error(AS_ERROR_UNSUPPORTED, "%s: %llu points, %llu faces (at most 2^32 - 1)",
                            name, (unsigned long long)points, (unsigned long long)faces);
    const draco::PointAttribute *pos = usable(m, draco::GeometryAttribute::POSITION, 3);
    if (!pos) return as_set_error(AS_ERROR_PARSE, "%s: the Draco mesh has no 3D positions", name);
    const draco::PointAttribute *nrm = usable(m, draco::GeometryAttribute::NORMAL, 3);
    const draco::PointAttribute *tex = usable(m, draco::GeometryAttribute::TEX_COORD, 2);
    const draco::PointAttribute *mat = usable(m, draco::GeometryAttribute::MATERIAL, 1);

    mesh->vertex_count = uint32_t(points);
    mesh->triangle_count = uint32_t(faces);
    mesh->faces_in_file = faces;
    mesh->positions = static_cast<float *>(as_malloc(points * 3 * sizeof(float) + 1, "positions"));
    mesh->indices = static_cast<uint32_t *>(as_malloc(faces * 3 * sizeof(uint32_t) + 1, "indices"));
    if (nrm) mesh->normals = static_cast<float *>(as_malloc(points * 3 * sizeof(float) + 1, "normals"));
    if (tex) mesh->uvs = static_cast<float *>(as_malloc(points * 2 * sizeof(float) + 1, "UVs"));
    if (mat)
        mesh->material_ids = static_cast<uint32_t *>(
            as_malloc(faces * sizeof(uint32_t) + 1, "material ids"));
    if (!mesh->positions || !mesh->indices || (nrm && !mesh->normals) || (tex && !mesh->uvs) ||
        (mat && !mesh->material_ids))
        return AS_ERROR_OUT_OF_MEMORY;

    if (!copy_attribute(*pos, uint32_t(points), 3, mesh->positions) ||
        (nrm && !copy_attribute(*nrm, uint32_t(points), 3, mesh->normals)) ||
        (tex && !copy_attribute(*tex, uint32_t(points), 2, mesh->uvs)))
        return as_set_error(AS_ERROR_PARSE, "%s: a Draco attribute cannot be read as floats", name);

    for (uint32_t f = 0; f < faces; ++f) {
        const draco::Mesh::Face &face = m.face(draco::FaceIndex(f));
        for (int c = 0; c < 3; ++c) mesh->indices[size_t(f) * 3 + c] = face[c].value();
        if (mat) {
            /* Material is per point in Draco; a face takes its first corner's. */
            uint32_t id = 0;
            if (!mat->ConvertValue<uint32_t>(mat->mapped_index(face[0]), 1, &id))
                return as_set_error(AS_ERROR_PARSE, "%s: the Draco material of face %u cannot be read",
                                    name, f);
            mesh->material_ids[f] = id;
        }
    }
    return AS_OK;
}

} // namespace

extern "C" as_error_t as_mesh_read_draco(const void *data, size_t size, const char *name,
                                         as_mesh_t *mesh)
{
    std::memset(mesh, 0, sizeof *mesh);
    as_error_t err;
    try {
        err = read_draco(data, size, name, mesh);
    } catch (const std::bad_alloc &) {
        err = as_set_error(AS_ERROR_OUT_OF_MEMORY, "%s: out of memory while decoding", name);
    } catch (const std::exception &e) {
        err = as_set_error(AS_ERROR_PARSE, "%s: cannot decode as Draco (%s)", name, e.what());
    } catch (...) {
        err = as_set_error(AS_ERROR_PARSE, "%s: cannot decode as Draco", name);
    }
    if (err != AS_OK) {
        std::free(mesh->positions);
        std::free(mesh->indices);
        std::free(mesh->normals);
        std::free(mesh->uvs);
        std::free(mesh->material_ids);
        std::memset(mesh, 0, sizeof *mesh);
    }
    return err;
}

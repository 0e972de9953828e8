#pragma once
//! Dilation, closing and the chamfer distance transform of binary images, as OpenCV's cv::dilate,
//! cv::morphologyEx(MORPH_CLOSE) with a square kernel, and cv::distanceTransform (DIST_L2,
//! DIST_MASK_3) compute them for images of 0 and 255 and a radius of at least 1, to the bit (other
//! nonzero values are taken as 255, and a radius of 0 copies the image so), without allocating once their scratch has
//! grown: OpenCV's public API builds its filter objects, kernels and buffers at every call (88 to
//! 192 allocations a frame set in the zipper). Pixels outside the image do not count, as with
//! OpenCV's default border for morphology. Per-pixel passes over rows, as plain loops.

#include <cstdint>
#include <vector>

namespace zipfusion {

//! Buffers the functions below reuse from one call to the next.
struct BinaryImageScratch {
  std::vector<std::uint8_t> rows, padded, closed;
  std::vector<std::uint32_t> distances;
};

//! out = 255 where the (2·radius+1)² square around the pixel holds a nonzero pixel of `in`, else
//! 0 (cv::dilate with a square kernel). `out` may be `in`. Images of width × height, rows packed.
void dilate_binary(const std::uint8_t* in, std::uint8_t* out, int width, int height, int radius, BinaryImageScratch& scratch);

//! out = 0 where the square around the pixel holds a zero pixel of `in`, else 255 (cv::erode).
void erode_binary(const std::uint8_t* in, std::uint8_t* out, int width, int height, int radius, BinaryImageScratch& scratch);

//! Dilation, then erosion, by the same square (cv::morphologyEx with MORPH_CLOSE): fills holes
//! and gaps up to 2·radius+1 pixels wide. `out` may be `in`.
void close_binary(const std::uint8_t* in, std::uint8_t* out, int width, int height, int radius, BinaryImageScratch& scratch);

//! The distance of every pixel of `in` to the nearest zero pixel, in pixels, along the shortest
//! path of steps to the 8 neighbours, straight ones 0.955 long and diagonal ones 1.3693 (Borgefors
//! 1986; OpenCV's 3×3 approximation of the Euclidean distance, in 16-bit fixed point as it
//! computes it): 0 on zero pixels. An image without a zero pixel reads 8192 everywhere.
void chamfer_distance(const std::uint8_t* in, float* out, int width, int height, BinaryImageScratch& scratch);

}  // namespace zipfusion
